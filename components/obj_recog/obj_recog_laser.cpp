#include "obj_recog/obj_recog_laser.h"

#include <algorithm>
#include <cmath>

namespace rack::components {

using interfaces::ObjRecogData;
using interfaces::Scan2dData;

ObjRecogLaser::ObjRecogLaser()
    : DataComponent(DataTaskMode::kTriggered),
      scan2d_(
          declare_input<Scan2dData>("scan2d", {.doc = "the Scan2D component whose scans are clustered and tracked"})),
      cluster_gap_(
          declare_float("cluster_gap", 0.25,
                        {.doc = "m, neighbouring points closer than this form one cluster", .min = 0.01, .max = 10.0})),
      cluster_min_points_(
          declare_int("cluster_min_points", 3, {.doc = "fewer points: not an object", .min = 1, .max = 1000})),
      cluster_max_size_(declare_float(
          "cluster_max_size", 1.0, {.doc = "m, larger clusters (walls) are not objects", .min = 0.01, .max = 100.0})),
      gate_(declare_float("gate", 0.8,
                          {.doc = "m, association gate around a track's prediction", .min = 0.01, .max = 100.0})),
      confirm_hits_(
          declare_int("confirm_hits", 3, {.doc = "associations before a track is published", .min = 1, .max = 1000})),
      max_missed_(declare_int("max_missed", 5,
                              {.doc = "scans without association before a track is dropped", .min = 0, .max = 1000})),
      accel_std_(declare_float(
          "accel_std", 2.0,
          {.doc = "m/s^2, process noise (how abruptly objects change speed)", .min = 1e-3, .max = 100.0})),
      measurement_std_(
          declare_float("measurement_std", 0.05, {.doc = "m, noise of a cluster's centre", .min = 1e-4, .max = 10.0})),
      dynamic_min_speed_(
          declare_float("dynamic_min_speed", 0.25,
                        {.doc = "m/s, informational: the speed Scan2D calls dynamic", .min = 0.0, .max = 100.0})) {}

HookResult ObjRecogLaser::on() {
  TrackerOptions o;
  o.cluster_gap = cluster_gap_.get_float();
  o.cluster_min_points = static_cast<uint32_t>(cluster_min_points_.get_int());
  o.cluster_max_size = cluster_max_size_.get_float();
  o.gate = gate_.get_float();
  o.confirm_hits = static_cast<uint32_t>(confirm_hits_.get_int());
  o.max_missed = static_cast<uint32_t>(max_missed_.get_int());
  o.accel_std = accel_std_.get_float();
  o.measurement_std = measurement_std_.get_float();
  o.dynamic_min_speed = dynamic_min_speed_.get_float();
  tracker_.set_options(o);
  tracker_.reset();
  out_ = ObjRecogData{};
  return HookResult::kOk;
}

void ObjRecogLaser::fill(const LaserTracker& tracker, ObjRecogData& out) noexcept {
  const Pose2d& robot = tracker.robot_pose();
  const double c = std::cos(robot.phi), s = std::sin(robot.phi);
  uint32_t n = 0;
  for (uint32_t i = 0; i < tracker.cluster_count() && n < interfaces::kObjRecogMaxObjects; ++i) {
    const LaserTracker::Cluster& cl = tracker.cluster(i);
    if (cl.track < 0) continue;
    const LaserTracker::Track& t = tracker.track(static_cast<uint32_t>(cl.track));
    if (!t.confirmed) continue;
    // The filtered position, taken back into the robot frame at the scan's time.
    const double dx = t.x - robot.x, dy = t.y - robot.y;
    out.id[n] = t.id;
    out.type[n] = interfaces::kObjTypeLaserCluster;
    out.probability[n] = static_cast<float>(
        std::min(1.0, static_cast<double>(t.hits) / (2.0 * tracker.options().confirm_hits)));
    out.x[n] = static_cast<float>(c * dx + s * dy);
    out.y[n] = static_cast<float>(-s * dx + c * dy);
    out.z[n] = 0.0F;
    out.roll[n] = out.pitch[n] = out.yaw[n] = 0.0F;
    out.vx[n] = static_cast<float>(c * t.vx + s * t.vy);
    out.vy[n] = static_cast<float>(-s * t.vx + c * t.vy);
    out.vz[n] = 0.0F;
    out.size_x[n] = static_cast<float>(cl.size_x);
    out.size_y[n] = static_cast<float>(cl.size_y);
    out.size_z[n] = 0.0F;
    out.image_x[n] = out.image_y[n] = out.image_width[n] = out.image_height[n] = 0;
    ++n;
  }
  out.object_count = n;
  out.frame = interfaces::kObjFrameRobot;
}

HookResult ObjRecogLaser::loop() {
  const Received r = receive([&](const InputPort&) {
    const Scan2dData& scan = scan2d_.value();
    const int64_t t0 = rt::monotonic_ns();
    if (scan.point_count == 0 || scan.point_count > interfaces::kScan2dMaxPoints) {
      ++out_.bad_input;
      if (out_.bad_input == 1 || out_.bad_input % 100 == 0) {
        log_warning("skipped an empty or malformed scan (%u points); %u so far", scan.point_count, out_.bad_input);
      }
      return;
    }
    const Pose2d robot = scan.odometry_valid != 0 ? Pose2d{scan.odometry_x, scan.odometry_y, scan.odometry_phi}
                                                  : Pose2d{};
    tracker_.update(scan, robot, scan2d_.time_ns());
    ++out_.inputs;
    fill(tracker_, out_);
    out_.process_ms = static_cast<float>(rt::monotonic_ns() - t0) * 1e-6F;
    publish(out_, scan2d_.time_ns());
  });
  return r.failed ? HookResult::kError : HookResult::kOk;  // the Scan2D left ENABLED or fell silent
}

}  // namespace rack::components
