// Assembles one 3-D scan from 2-D ladar scans taken while a servo drive turns the
// ladar (RACK's roll, pitch and yaw modes, components/common/scan3d_geometry.h). Each
// beam is placed with the drive angle at the beam's own time (the scan's time plus
// its share of the scan's duration), interpolated in the drive's position stream.
//
// Motion compensation (AssemblerConfig::compensate_motion, fed by add_pose() from an
// Odometry or Position stream): each beam's point is also moved by the robot's pose
// at the beam's time (interpolated in a ring of the last 256 poses), and
// to_end_frame() finally expresses every point in the robot frame at the END of the
// sweep (last_time_ns()): a robot driving during a sweep sees a wall ahead as thin
// as a robot standing still. Points are kept relative to the sweep's first pose until
// then (floats stay small far from the odometry's origin). A scan waits until the
// poses cover it as it waits for the drive.
//
// No PCL here: this is the part of Scan3D that can run in a real-time task.
//
// Real-time contract: the constructor allocates (call it from init()); everything
// else is RT-safe (fixed buffers, no allocation). One thread.
#pragma once

#include <cstdint>
#include <memory>

#include "common/pose2d.h"
#include "common/pose_series.h"
#include "common/scan3d_geometry.h"
#include "common/time_series.h"
#include "rack/interfaces/robot.h"

namespace rack::scan3d {

struct AssemblerConfig {
  components::Scan3dMount mount;
  double range_min = 0.05;  // m: closer echoes are the robot or the drive
  double range_max = 0.0;   // m: 0: the ladar's own max_range
  // How far past the drive's newest sample a beam may be and still use it (held).
  int64_t max_extrapolation_ns = 50'000'000;
  // Undo the robot's motion with the poses given to add_pose() (no extrapolation:
  // every beam's time must lie between two poses).
  bool compensate_motion = false;
};

enum class AddStatus : uint8_t {
  kAdded,         // the scan's points were added (some may have been dropped: full)
  kWaitForDrive,  // the drive has not reported the scan's end yet: call again later
  kNoDriveAngle,  // the scan is older than the drive history: skipped
  kEmpty,         // no beam with an echo: skipped
  kMalformed,     // beam_count 0 or above the capacity, non-finite angles: skipped
  kWaitForPose,   // compensate_motion: no pose at or after the scan's end yet: call again later
  kNoPose,        // compensate_motion: the scan is older than the pose history: skipped
};
[[nodiscard]] const char* describe(AddStatus s) noexcept;

class Scan3dAssembler {
 public:
  explicit Scan3dAssembler(uint32_t capacity);

  void set_config(const AssemblerConfig& c) noexcept { config_ = c; }
  [[nodiscard]] const AssemblerConfig& config() const noexcept { return config_; }

  // Starts a new 3-D scan (the drive and pose histories are kept).
  void reset() noexcept;
  // The drive's position stream (radians), in time order.
  void add_drive_sample(int64_t time_ns, double angle) noexcept { drive_.push(time_ns, angle); }
  [[nodiscard]] int64_t drive_newest_time() const noexcept { return drive_.newest_time(); }
  // The robot's pose stream (odometry or map frame), in time order; the caller skips
  // poses that are not finite. false: not newer than the newest (ignored).
  bool add_pose(int64_t time_ns, const components::Pose2d& pose) noexcept { return poses_.push(time_ns, pose); }
  // Forgets the poses (after a silence: no interpolation across the gap).
  void clear_poses() noexcept { poses_.clear(); }
  [[nodiscard]] std::size_t poses() const noexcept { return poses_.size(); }
  [[nodiscard]] int64_t pose_oldest_time() const noexcept { return poses_.oldest_time(); }
  [[nodiscard]] int64_t pose_newest_time() const noexcept { return poses_.newest_time(); }
  // One ladar scan that started at time_ns.
  [[nodiscard]] AddStatus add_scan(const interfaces::LadarData& scan, int64_t time_ns) noexcept;
  // compensate_motion: moves every point into the robot frame at last_time_ns() (the
  // end of the newest scan added); call once, when the sweep is complete, before
  // reading the points. false (points unchanged) without compensation or without a
  // scan. Without it the points are in the frame of the sweep's first pose.
  bool to_end_frame() noexcept;

  [[nodiscard]] uint32_t size() const noexcept { return count_; }
  [[nodiscard]] uint32_t capacity() const noexcept { return capacity_; }
  [[nodiscard]] uint32_t scans() const noexcept { return scans_; }
  [[nodiscard]] uint32_t dropped_points() const noexcept { return dropped_; }
  [[nodiscard]] int64_t first_time_ns() const noexcept { return first_ns_; }
  [[nodiscard]] int64_t last_time_ns() const noexcept { return last_ns_; }
  [[nodiscard]] const float* x() const noexcept { return x_.get(); }
  [[nodiscard]] const float* y() const noexcept { return y_.get(); }
  [[nodiscard]] const float* z() const noexcept { return z_.get(); }
  [[nodiscard]] const float* intensity() const noexcept { return i_.get(); }

 private:
  AssemblerConfig config_;
  components::TimeSeries<1024> drive_;
  components::PoseSeries<256> poses_;
  components::Pose2d anchor_;  // compensate_motion: the pose the points are relative to
  bool in_end_frame_ = false;
  uint32_t capacity_;
  std::unique_ptr<float[]> x_, y_, z_, i_;
  uint32_t count_ = 0;
  uint32_t scans_ = 0;
  uint32_t dropped_ = 0;
  int64_t first_ns_ = 0;
  int64_t last_ns_ = 0;
};

}  // namespace rack::scan3d
