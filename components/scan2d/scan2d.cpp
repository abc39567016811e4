#include "scan2d/scan2d.h"

#include <algorithm>
#include <cmath>

#include "common/pose2d.h"

namespace rack::components {

using interfaces::LadarData;
using interfaces::OdometryData;
using interfaces::Scan2dData;

Scan2d::Scan2d()
    : DataComponent(DataTaskMode::kTriggered),
      ladar_(declare_component_ref("ladar", "the Ladar whose scans to convert")),
      odometry_(declare_string("odometry", "", {.doc = "optional Odometry: fills odometry_* at each scan's time", .component_ref = true})),
      mount_x_(declare_float("mount_x", 0.0, {.doc = "m, sensor position in the robot frame (forward)", .min = -10.0, .max = 10.0})),
      mount_y_(declare_float("mount_y", 0.0, {.doc = "m, sensor position in the robot frame (left)", .min = -10.0, .max = 10.0})),
      mount_phi_(declare_float("mount_phi", 0.0, {.doc = "rad, sensor heading in the robot frame", .min = -7.0, .max = 7.0})),
      range_min_(declare_float("range_min", 0.05, {.doc = "m, shorter ranges are dropped (the robot's own body)", .min = 0.0, .max = 1000.0})),
      range_max_(declare_float("range_max", 0.0, {.doc = "m, longer ranges count as no echo (0: the ladar's max)", .min = 0.0, .max = 1000.0})),
      median_(declare_int("median", 1, {.doc = "median filter window over neighbouring beams (odd; 1: off)", .min = 1, .max = 9})),
      keep_max_range_(declare_bool("keep_max_range", true, {.doc = "beams without echo become max-range points (else left out)"})),
      dynamic_objects_(declare_bool("dynamic_objects", false, {.doc = "track small clusters; mark moving ones DYN_OBSTACLE (type 2)"})),
      dynamic_min_speed_(declare_float("dynamic_min_speed", 0.25, {.doc = "m/s, a tracked cluster faster than this is dynamic", .min = 0.0, .max = 100.0})),
      cluster_gap_(declare_float("cluster_gap", 0.25, {.doc = "m, neighbouring points closer than this form one cluster", .min = 0.01, .max = 10.0})),
      cluster_max_size_(declare_float("cluster_max_size", 1.0, {.doc = "m, larger clusters (walls) are not tracked", .min = 0.01, .max = 100.0})) {
  use_input_mailbox(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(LadarData) + 64);
}

void Scan2d::convert(const LadarData& ladar, const Geometry& g, Scan2dData& out) noexcept {
  const uint32_t n = std::min(ladar.beam_count, interfaces::kLadarMaxBeams);
  const double max_range =
      g.range_max > 0.0 ? std::min(g.range_max, static_cast<double>(ladar.max_range)) : static_cast<double>(ladar.max_range);
  const double min_range = std::max(g.range_min, static_cast<double>(ladar.min_range));
  const auto valid = [&](float r) { return std::isfinite(r) && r > 0.0F && static_cast<double>(r) <= max_range; };
  const int half = std::clamp(g.median, 1, 9) / 2;
  out.max_range = static_cast<float>(max_range);
  out.duration_ns = ladar.duration_ns;
  uint32_t k = 0;
  for (uint32_t i = 0; i < n; ++i) {
    const float raw = ladar.range[i];
    float r = raw;
    const bool echo = valid(raw);
    if (echo && half > 0) {
      // Median of the valid ranges in the window (at most 9: insertion sort).
      float w[9];
      int m = 0;
      const uint32_t lo = i >= static_cast<uint32_t>(half) ? i - static_cast<uint32_t>(half) : 0;
      const uint32_t hi = std::min(n - 1, i + static_cast<uint32_t>(half));
      for (uint32_t j = lo; j <= hi; ++j) {
        if (!valid(ladar.range[j])) continue;
        const float v = ladar.range[j];
        int at = m++;
        while (at > 0 && w[at - 1] > v) {
          w[at] = w[at - 1];
          --at;
        }
        w[at] = v;
      }
      r = w[m / 2];
    }
    uint8_t type = interfaces::kScanPointNormal;
    if (!echo) {
      if (!g.keep_max_range) continue;
      r = static_cast<float>(max_range);
      type = interfaces::kScanPointMaxRange;
    } else if (static_cast<double>(r) < min_range) {
      continue;  // too close: the robot itself, or the sensor's blind zone
    }
    const double bearing = static_cast<double>(ladar.start_angle) + static_cast<double>(i) * static_cast<double>(ladar.angle_step);
    const double a = g.mount_phi + bearing;
    out.x[k] = static_cast<float>(g.mount_x + static_cast<double>(r) * std::cos(a));
    out.y[k] = static_cast<float>(g.mount_y + static_cast<double>(r) * std::sin(a));
    out.range[k] = r;
    out.bearing[k] = static_cast<float>(bearing);
    out.type[k] = type;
    ++k;
  }
  out.point_count = k;
}

HookResult Scan2d::on() {
  odometry_misses_ = 0;
  tracker_.reset();
  const tims::Address ladar = resolved(ladar_);
  const tims::Address odo = resolved(odometry_);
  if (odo.raw() != 0 && switch_on(odo) != HookResult::kOk) return HookResult::kError;
  if (switch_on(ladar) != HookResult::kOk) return HookResult::kError;
  return subscribe(ladar, 0);
}

void Scan2d::off() { unsubscribe(resolved(ladar_)); }

void Scan2d::fill_odometry(int64_t time_ns) noexcept {
  scan_.odometry_valid = 0;
  const tims::Address odo = resolved(odometry_);
  if (odo.raw() == 0) return;
  wire::GetDataRequest get;
  get.time_ns = time_ns;
  alignas(8) std::byte buf[sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(OdometryData) + 160];
  const auto r = data_endpoint().call(odo, tims::msg::kGetData, get, std::span<std::byte>(buf), settings().rpc_timeout_ns);
  wire::SampleHeader sh;
  OdometryData o;
  if (r.status != tims::CallStatus::kOk || r.reply.type != tims::msg::kData || !read_sample(r.reply, r.body, sh, o)) {
    ++odometry_misses_;  // published without odometry (odometry_valid 0)
    return;
  }
  const double dt = static_cast<double>(time_ns - sh.time_ns) * 1e-9;
  const Pose2d p = compose(Pose2d{o.x, o.y, o.phi}, integrate_twist(o.vx, 0.0, o.omega, dt));
  scan_.odometry_x = p.x;
  scan_.odometry_y = p.y;
  scan_.odometry_phi = p.phi;
  scan_.odometry_valid = 1;
}

HookResult Scan2d::loop() {
  bool got = false;
  for (;;) {
    wire::SampleHeader sh;
    const Input in = next_sample(sh, ladar_data_);
    if (in == Input::kNone) break;
    if (in == Input::kError) return HookResult::kError;  // the ladar left ENABLED
    got = true;
    Geometry g;
    g.mount_x = mount_x_.get_float();
    g.mount_y = mount_y_.get_float();
    g.mount_phi = mount_phi_.get_float();
    g.range_min = range_min_.get_float();
    g.range_max = range_max_.get_float();
    g.median = static_cast<int>(median_.get_int()) | 1;
    g.keep_max_range = keep_max_range_.get_bool();
    convert(ladar_data_, g, scan_);
    fill_odometry(sh.time_ns);
    if (dynamic_objects_.get_bool()) {
      TrackerOptions o = tracker_.options();
      o.dynamic_min_speed = dynamic_min_speed_.get_float();
      o.cluster_gap = cluster_gap_.get_float();
      o.cluster_max_size = cluster_max_size_.get_float();
      tracker_.set_options(o);
      const Pose2d robot = scan_.odometry_valid != 0 ? Pose2d{scan_.odometry_x, scan_.odometry_y, scan_.odometry_phi} : Pose2d{};
      tracker_.update(scan_, robot, sh.time_ns);
      (void)tracker_.mark_dynamic(scan_);
    }
    publish(scan_, sh.time_ns);
  }
  // Nothing usable (a renewal's reply, a refused wake-up): an error only once silent.
  return got || !input_silent() ? HookResult::kOk : HookResult::kError;  // else the ladar fell silent
}

}  // namespace rack::components
