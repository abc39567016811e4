#include "scan2d/scan2d.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "common/pose2d.h"

namespace rack::components {

using interfaces::LadarData;
using interfaces::OdometryData;
using interfaces::Scan2dData;

Scan2d::Scan2d()
    : DataComponent(DataTaskMode::kTriggered),
      odometry_(declare_input<OdometryData>(
          "odometry", {.doc = "Odometry: fills odometry_* at each scan's time", .optional = true, .watched = false})),
      ladar_(declare_input<LadarData>("ladar", {.doc = "the Ladar whose scans to convert"})),
      mount_x_(declare_float("mount_x", 0.0,
                             {.doc = "m, sensor position in the robot frame (forward)", .min = -10.0, .max = 10.0})),
      mount_y_(declare_float("mount_y", 0.0,
                             {.doc = "m, sensor position in the robot frame (left)", .min = -10.0, .max = 10.0})),
      mount_phi_(
          declare_float("mount_phi", 0.0, {.doc = "rad, sensor heading in the robot frame", .min = -7.0, .max = 7.0})),
      range_min_(
          declare_float("range_min", 0.05,
                        {.doc = "m, shorter ranges are dropped (the robot's own body)", .min = 0.0, .max = 1000.0})),
      range_max_(
          declare_float("range_max", 0.0,
                        {.doc = "m, longer ranges count as no echo (0: the ladar's max)", .min = 0.0, .max = 1000.0})),
      median_(declare_int("median", 1,
                          {.doc = "median filter window over neighbouring beams (odd; 1: off)", .min = 1, .max = 9})),
      keep_max_range_(
          declare_bool("keep_max_range", true, {.doc = "beams without echo become max-range points (else left out)"})),
      dynamic_objects_(declare_bool("dynamic_objects", false,
                                    {.doc = "track small clusters; mark moving ones DYN_OBSTACLE (type 2)"})),
      dynamic_min_speed_(
          declare_float("dynamic_min_speed", 0.25,
                        {.doc = "m/s, a tracked cluster faster than this is dynamic", .min = 0.0, .max = 100.0})),
      cluster_gap_(
          declare_float("cluster_gap", 0.25,
                        {.doc = "m, neighbouring points closer than this form one cluster", .min = 0.01, .max = 10.0})),
      cluster_max_size_(declare_float(
          "cluster_max_size", 1.0, {.doc = "m, larger clusters (walls) are not tracked", .min = 0.01, .max = 100.0})),
      odometry_wait_ms_(declare_float(
          "odometry_wait_ms", 500.0,
          {.doc = "ms a scan waits for odometry at or after its time before it goes out without (counted)",
           .min = 0.0,
           .max = 600000.0,
           .unit = "ms"})),
      held_(std::make_unique<LadarData[]>(kHeld)) {}

Scan2d::OdometryCounts Scan2d::odometry_counts() const noexcept {
  OdometryCounts c;
  c.interpolated = odometry_interpolated_.load(std::memory_order_relaxed);
  c.missing = odometry_missing_.load(std::memory_order_relaxed);
  return c;
}

void Scan2d::describe_status(std::string& out) const {
  if (odometry_.source_parameter().get_string().empty()) return;
  const OdometryCounts c = odometry_counts();
  char line[200];
  std::snprintf(line, sizeof line, "odometry per scan: %llu interpolated (never extrapolated), %llu missing",
                static_cast<unsigned long long>(c.interpolated), static_cast<unsigned long long>(c.missing));
  out += line;
}

void Scan2d::convert(const LadarData& ladar, const Geometry& g, Scan2dData& out) noexcept {
  const uint32_t n = std::min(ladar.beam_count, interfaces::kLadarMaxBeams);
  const double max_range = g.range_max > 0.0 ? std::min(g.range_max, static_cast<double>(ladar.max_range))
                                             : static_cast<double>(ladar.max_range);
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
    const double bearing = static_cast<double>(ladar.start_angle) +
                           static_cast<double>(i) * static_cast<double>(ladar.angle_step);
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
  tracker_.reset();
  poses_.clear();
  held_head_ = held_count_ = 0;
  odometry_interpolated_.store(0, std::memory_order_relaxed);
  odometry_missing_.store(0, std::memory_order_relaxed);
  use_odometry_ = odometry_.configured();
  return HookResult::kOk;
}

void Scan2d::convert_and_publish(const LadarData& ladar, int64_t time_ns) noexcept {
  Geometry g;
  g.mount_x = mount_x_.get_float();
  g.mount_y = mount_y_.get_float();
  g.mount_phi = mount_phi_.get_float();
  g.range_min = range_min_.get_float();
  g.range_max = range_max_.get_float();
  g.median = static_cast<int>(median_.get_int()) | 1;
  g.keep_max_range = keep_max_range_.get_bool();
  convert(ladar, g, scan_);
  if (dynamic_objects_.get_bool()) {
    TrackerOptions o = tracker_.options();
    o.dynamic_min_speed = dynamic_min_speed_.get_float();
    o.cluster_gap = cluster_gap_.get_float();
    o.cluster_max_size = cluster_max_size_.get_float();
    tracker_.set_options(o);
    const Pose2d robot = scan_.odometry_valid != 0 ? Pose2d{scan_.odometry_x, scan_.odometry_y, scan_.odometry_phi}
                                                   : Pose2d{};
    tracker_.update(scan_, robot, time_ns);
    (void)tracker_.mark_dynamic(scan_);
  }
  publish(scan_, time_ns);
}

void Scan2d::release(bool flush) noexcept {
  const int64_t now = rt::monotonic_ns();
  const auto wait_ns = static_cast<int64_t>(odometry_wait_ms_.get_float() * 1e6);
  while (held_count_ > 0) {
    const std::size_t i = held_head_;
    const int64_t t = held_time_ns_[i];
    Pose2d p;
    SeriesLookup found = use_odometry_ ? poses_.pose_at(t, p) : SeriesLookup::kEmpty;
    if (found == SeriesLookup::kTooNew || found == SeriesLookup::kEmpty) {
      // Not there yet: wait, unless it has waited long enough or must make room.
      const bool waited = now - held_arrival_ns_[i] >= wait_ns;
      if (use_odometry_ && !flush && !waited && held_count_ < kHeld) return;
    }
    scan_.odometry_valid = 0;
    if (found == SeriesLookup::kOk) {
      scan_.odometry_x = p.x;
      scan_.odometry_y = p.y;
      scan_.odometry_phi = p.phi;
      scan_.odometry_valid = 1;
      odometry_interpolated_.fetch_add(1, std::memory_order_relaxed);
    } else if (use_odometry_) {
      odometry_missing_.fetch_add(1, std::memory_order_relaxed);
    }
    // convert() fills the points; the odometry fields above stay as set.
    convert_and_publish(held_[i], t);
    held_head_ = (held_head_ + 1) % kHeld;
    --held_count_;
  }
}

// One sample of the input: a scan (held) or an odometry sample (kept).
void Scan2d::take(const InputPort& from) noexcept {
  if (&from == &odometry_) {
    const OdometryData& o = odometry_.value();
    if (std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.phi))
      (void)poses_.push(odometry_.time_ns(), Pose2d{o.x, o.y, o.phi});
    return;
  }
  if (held_count_ == kHeld) release(false);  // cannot happen (release() makes room), but never overwrite
  const std::size_t slot = (held_head_ + held_count_) % kHeld;
  held_[slot] = ladar_.value();
  held_time_ns_[slot] = ladar_.time_ns();
  held_arrival_ns_[slot] = ladar_.received_ns();
  ++held_count_;
  release(false);  // makes room when full; the rest waits for the odometry below
}

HookResult Scan2d::loop() {
  const Received r = receive([&](const InputPort& from) { take(from); });
  if (r.failed) {  // the ladar or the odometry left ENABLED, or the ladar fell silent
    release(true);
    return HookResult::kError;
  }
  release(false);
  return HookResult::kOk;
}

}  // namespace rack::components
