#include "ladar_sim/ladar_sim.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "common/scan3d_geometry.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

using interfaces::ChassisData;
using interfaces::LadarData;

LadarSim::LadarSim()
    : DataComponent(DataTaskMode::kPeriodic),
      map_(declare_string("map", "",
                          {.doc = "map_server YAML file (relative: to the host file's folder)",
                           .required = true,
                           .init_only = true,
                           .path = PathRole::kInput})),
      chassis_(declare_input<ChassisData>(
          "chassis", {.doc = "the simulated Chassis whose true pose the scans are rendered from", .watched = false})),
      mount_x_(declare_float("mount_x", 0.0,
                             {.doc = "m, sensor position in the robot frame (forward)", .min = -10.0, .max = 10.0})),
      mount_y_(declare_float("mount_y", 0.0,
                             {.doc = "m, sensor position in the robot frame (left)", .min = -10.0, .max = 10.0})),
      mount_phi_(
          declare_float("mount_phi", 0.0, {.doc = "rad, sensor heading in the robot frame", .min = -7.0, .max = 7.0})),
      beams_(declare_int("beams", 541, {.doc = "beams per scan", .min = 2, .max = interfaces::kLadarMaxBeams})),
      fov_deg_(declare_float(
          "fov_deg", 270.0,
          {.doc = "field of view, centred on the sensor's axis", .min = 1.0, .max = 360.0, .unit = "deg"})),
      range_min_(declare_float("range_min", 0.05, {.doc = "m, the sensor's blind zone", .min = 0.0, .max = 100.0})),
      range_max_(declare_float("range_max", 20.0, {.doc = "m, no echo beyond", .min = 0.1, .max = 1000.0})),
      noise_sigma_(
          declare_float("noise_sigma", 0.01, {.doc = "m, std-dev of gaussian range noise", .min = 0.0, .max = 10.0})),
      seed_(declare_int("seed", 2, {.doc = "seed of the noise generator", .min = 0, .max = 1e15, .init_only = true})),
      servo_(declare_input<interfaces::ServoDriveData>(
          "servo", {.doc = "3-D: the ServoDrive that turns the ladar (empty: a fixed 2-D ladar)",
                    .optional = true,
                    .watched = false})),
      scan_mode_(declare_string("scan_mode", "pitch",
                                {.doc = "3-D: how the drive turns the scan plane (as Scan3D's mode)",
                                 .choices = {"roll", "pitch", "yaw"},
                                 .init_only = true})),
      mount_z_(declare_float("mount_z", 0.5,
                             {.doc = "3-D: m, the ladar's centre above the floor", .min = 0.0, .max = 100.0})),
      ceiling_height_(
          declare_float("ceiling_height", 2.5,
                        {.doc = "3-D: m, the ceiling (0: none); walls reach up to it", .min = 0.0, .max = 1000.0})) {}

void LadarSim::init() {
  const std::string path = map_.get_string();
  auto loaded = maps::load_map(path);
  if (!loaded.ok()) throw std::runtime_error("map: " + loaded.error_text());
  map_data_ = std::move(loaded.map);
  rng_.seed(static_cast<uint64_t>(seed_.get_int()));
  three_d_ = !servo_.source_parameter().get_string().empty();
  const std::string mode = scan_mode_.get_string();
  mode_id_ = mode == "roll"  ? interfaces::kScan3dModeRoll
             : mode == "yaw" ? interfaces::kScan3dModeYaw
                             : interfaces::kScan3dModePitch;
}

double LadarSim::cast_3d(const Pose2d& robot, double theta, double bearing, double range_max) const noexcept {
  const Vec3 d = scan3d_direction(mode_id_, theta, bearing);  // robot frame
  const double c = std::cos(robot.phi), s = std::sin(robot.phi);
  const double dx = c * d.x - s * d.y, dy = s * d.x + c * d.y, dz = d.z;
  const double mx = mount_x_.get_float(), my = mount_y_.get_float();
  const double x0 = robot.x + c * mx - s * my, y0 = robot.y + s * mx + c * my, z0 = mount_z_.get_float();
  const double ceiling = ceiling_height_.get_float();
  double limit = range_max;
  if (dz < -1e-12) limit = std::min(limit, -z0 / dz);                             // the floor
  if (ceiling > 0.0 && dz > 1e-12) limit = std::min(limit, (ceiling - z0) / dz);  // the ceiling
  const double h = std::hypot(dx, dy);
  if (h > 1e-9) {  // walls: the map's occupied cells, floor to ceiling
    const maps::RayHit hit = map_data_->cast_ray(x0, y0, std::atan2(dy, dx), limit * h);
    if (hit.hit && static_cast<double>(hit.range) / h < limit) return static_cast<double>(hit.range) / h;
  }
  return limit < range_max ? limit : 0.0;
}

HookResult LadarSim::on() {
  have_truth_ = false;
  published_time_ns_ = 0;
  last_truth_mono_ns_ = rt::monotonic_ns();
  servo_angle_.clear();
  return HookResult::kOk;
}

HookResult LadarSim::loop() {
  const int64_t now = rt::monotonic_ns();
  // The newest true pose (and, in 3-D, every drive angle).
  const Received got = receive([&](const InputPort& from) {
    if (&from == &servo_) {
      if (std::isfinite(servo_.value().position)) servo_angle_.push(servo_.time_ns(), servo_.value().position);
      return;
    }
    const ChassisData& c = chassis_.value();
    if (c.truth_valid != 0) {
      truth_ = Pose2d{c.truth_x, c.truth_y, c.truth_phi};
      truth_time_ns_ = chassis_.time_ns();
      last_truth_mono_ns_ = now;
      have_truth_ = true;
    }
  });
  if (got.failed) return HookResult::kError;  // the chassis (or the drive) left ENABLED
  if (now - last_truth_mono_ns_ > silence_ns()) {
    set_error_reason("the chassis sent no true pose for silence_ms");
    return HookResult::kError;
  }
  // Nothing to render from yet, or no new pose since the last scan (one scan per pose).
  if (!have_truth_ || truth_time_ns_ == published_time_ns_) return HookResult::kOk;
  double theta = 0.0;
  if (three_d_) {
    // The drive's angle at the pose's time; a pose newer than the drive's last sample
    // waits for the next cycle (a short hold covers a drive that stands still).
    const SeriesLookup l = servo_angle_.value_at(truth_time_ns_, 20 * rt::kNsPerMs, theta);
    if (l == SeriesLookup::kTooNew || l == SeriesLookup::kEmpty) return HookResult::kOk;
    if (l == SeriesLookup::kTooOld) theta = servo_angle_.newest_value();
  }

  const Pose2d sensor = compose(truth_, Pose2d{mount_x_.get_float(), mount_y_.get_float(), mount_phi_.get_float()});
  const auto n = static_cast<uint32_t>(beams_.get_int());
  const double fov = fov_deg_.get_float() * std::numbers::pi / 180.0;
  // A full circle must not render its first direction twice.
  const double step = fov >= 2.0 * std::numbers::pi - 1e-9 ? fov / n : fov / (n - 1);
  const double start = -fov / 2.0;
  const double range_max = range_max_.get_float();
  const double range_min = range_min_.get_float();
  const double sigma = noise_sigma_.get_float();
  scan_.duration_ns = 0;  // rendered at one instant
  scan_.max_range = static_cast<float>(range_max);
  scan_.min_range = static_cast<float>(range_min);
  scan_.start_angle = static_cast<float>(start);
  scan_.angle_step = static_cast<float>(step);
  scan_.beam_count = n;
  for (uint32_t i = 0; i < n; ++i) {
    double r = 0.0;  // no echo
    if (three_d_) {
      r = cast_3d(truth_, theta, start + static_cast<double>(i) * step, range_max);
    } else {
      const double a = sensor.phi + start + static_cast<double>(i) * step;
      const maps::RayHit hit = map_data_->cast_ray(sensor.x, sensor.y, a, range_max);
      r = hit.hit ? static_cast<double>(hit.range) : 0.0;
    }
    const bool echo = r > 0.0;
    if (echo) {
      r += sigma > 0.0 ? sigma * normal_(rng_) : 0.0;
      if (r < range_min) r = range_min;
      if (r > range_max) r = 0.0;
    }
    scan_.range[i] = static_cast<float>(r);
    scan_.intensity[i] = echo ? 1.0F : 0.0F;
  }
  publish(scan_, truth_time_ns_);
  published_time_ns_ = truth_time_ns_;
  return HookResult::kOk;
}

}  // namespace rack::components
