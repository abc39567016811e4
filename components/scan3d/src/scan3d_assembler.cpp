#include "rack/scan3d/scan3d_assembler.h"

#include <algorithm>
#include <cmath>

namespace rack::scan3d {

const char* describe(AddStatus s) noexcept {
  switch (s) {
    case AddStatus::kAdded: return "added";
    case AddStatus::kWaitForDrive: return "waiting for the drive's position at the scan's end";
    case AddStatus::kNoDriveAngle: return "scan older than the drive's position history";
    case AddStatus::kEmpty: return "no beam with an echo";
    case AddStatus::kMalformed: return "malformed ladar scan (beam count or angles)";
    case AddStatus::kWaitForPose: return "waiting for the robot's pose at the scan's end";
    case AddStatus::kNoPose: return "scan older than the robot's pose history (odometry)";
  }
  return "?";
}

Scan3dAssembler::Scan3dAssembler(uint32_t capacity)
    : capacity_(capacity),
      x_(std::make_unique<float[]>(capacity)),
      y_(std::make_unique<float[]>(capacity)),
      z_(std::make_unique<float[]>(capacity)),
      i_(std::make_unique<float[]>(capacity)) {}

void Scan3dAssembler::reset() noexcept {
  count_ = 0;
  scans_ = 0;
  dropped_ = 0;
  first_ns_ = 0;
  last_ns_ = 0;
  anchor_ = components::Pose2d{};
  in_end_frame_ = false;
}

AddStatus Scan3dAssembler::add_scan(const interfaces::LadarData& scan, int64_t time_ns) noexcept {
  if (scan.beam_count == 0 || scan.beam_count > interfaces::kLadarMaxBeams || !std::isfinite(scan.start_angle) ||
      !std::isfinite(scan.angle_step) || scan.duration_ns < 0) {
    return AddStatus::kMalformed;
  }
  const int64_t end_ns = time_ns + scan.duration_ns;
  double probe = 0.0;
  const components::SeriesLookup first = drive_.value_at(time_ns, config_.max_extrapolation_ns, probe);
  if (first == components::SeriesLookup::kTooOld) return AddStatus::kNoDriveAngle;
  // The whole scan must lie inside the drive's history (interpolation, not guessing).
  if (drive_.size() == 0 || drive_.newest_time() < end_ns) return AddStatus::kWaitForDrive;
  const bool compensate = config_.compensate_motion;
  if (compensate) {
    if (poses_.size() == 0 || poses_.newest_time() < end_ns) return AddStatus::kWaitForPose;
    if (time_ns < poses_.oldest_time()) return AddStatus::kNoPose;
    // The first scan of a sweep fixes the frame the points are kept in.
    if (scans_ == 0 && count_ == 0 && dropped_ == 0) (void)poses_.pose_at(time_ns, anchor_);
  }

  const double max_range = config_.range_max > 0.0 ? std::min(config_.range_max, static_cast<double>(scan.max_range))
                                                   : static_cast<double>(scan.max_range);
  const double min_range = std::max(config_.range_min, static_cast<double>(scan.min_range));
  const uint32_t n = scan.beam_count;
  uint32_t added = 0;
  for (uint32_t b = 0; b < n; ++b) {
    const double r = scan.range[b];
    if (!std::isfinite(r) || r <= 0.0 || r > max_range || r < min_range) continue;  // no echo / blind zone
    const int64_t t = n > 1 ? time_ns + scan.duration_ns * static_cast<int64_t>(b) / static_cast<int64_t>(n - 1)
                            : time_ns;
    double theta = 0.0;
    if (drive_.value_at(t, config_.max_extrapolation_ns, theta) != components::SeriesLookup::kOk) continue;
    if (count_ >= capacity_) {
      ++dropped_;
      continue;
    }
    const double bearing = static_cast<double>(scan.start_angle) +
                           static_cast<double>(b) * static_cast<double>(scan.angle_step);
    components::Vec3 p = components::scan3d_point(config_.mount, theta, bearing, r);
    if (compensate) {
      components::Pose2d pose;  // covered: checked above for the whole scan
      if (poses_.pose_at(t, pose) != components::SeriesLookup::kOk) continue;
      const components::Pose2d rel = components::between(anchor_, pose);
      const double c = std::cos(rel.phi), s = std::sin(rel.phi);
      p = components::Vec3{rel.x + c * p.x - s * p.y, rel.y + s * p.x + c * p.y, p.z};
    }
    x_[count_] = static_cast<float>(p.x);
    y_[count_] = static_cast<float>(p.y);
    z_[count_] = static_cast<float>(p.z);
    i_[count_] = scan.intensity[b];
    ++count_;
    ++added;
  }
  if (added == 0 && dropped_ == 0) return AddStatus::kEmpty;
  if (scans_ == 0) first_ns_ = time_ns;
  last_ns_ = end_ns;
  ++scans_;
  return AddStatus::kAdded;
}

bool Scan3dAssembler::to_end_frame() noexcept {
  if (!config_.compensate_motion || scans_ == 0 || in_end_frame_) return false;
  components::Pose2d end;
  if (poses_.pose_at(last_ns_, end) != components::SeriesLookup::kOk) return false;  // add_scan checked it
  // A point q in the anchor's frame is anchor (+) q in the odometry frame, and
  // end^-1 (+) anchor (+) q in the robot frame at the end.
  const components::Pose2d t = components::between(end, anchor_);
  const double c = std::cos(t.phi), s = std::sin(t.phi);
  for (uint32_t i = 0; i < count_; ++i) {
    const double px = static_cast<double>(x_[i]), py = static_cast<double>(y_[i]);
    x_[i] = static_cast<float>(t.x + c * px - s * py);
    y_[i] = static_cast<float>(t.y + s * px + c * py);
  }
  in_end_frame_ = true;
  return true;
}

}  // namespace rack::scan3d
