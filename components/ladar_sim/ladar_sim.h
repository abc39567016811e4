// LadarSim (class Ladar): a simulated planar laser scanner. Each period it ray-casts
// the occupancy map (ROS map_server YAML + PGM, parameter `map`) from the simulated
// chassis' TRUE pose (ChassisData truth_*, via getContData) composed with the
// mounting offset, adds seeded gaussian range noise, and publishes a LadarData scan
// stamped with the time of the chassis sample it was rendered from (so the scan and
// the odometry refer to the same moment). Beams that hit nothing within range_max
// report 0 (no echo).
//
// The map is read in init(): a missing or malformed map puts the component in ERROR
// for good with the loader's message (file and line or byte offset); the rest of the
// executor keeps running.
//
// 3-D (for Scan3D): with a `servo` (a ServoDrive component), the ladar turns on that
// drive in `scan_mode` (roll, pitch, yaw: components/common/scan3d_geometry.h), its
// centre `mount_z` above the floor, and the world is 2.5-D: a floor at z = 0, the
// map's occupied cells as walls up to the ceiling, a ceiling at `ceiling_height` (0:
// none). Each scan is rendered at the drive's angle at the chassis sample's time,
// interpolated in the drive's position stream (a scan waits for the drive's next
// sample). mount_phi is not used in 3-D (Scan3D's geometry has no heading offset).
//
// Real-time contract: on(), off() and loop() are RT-safe (the map is immutable after
// init(); ray casting does not allocate).
#pragma once

#include <optional>
#include <random>

#include "common/pose2d.h"
#include "common/time_series.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/robot.h"
#include "rack/maps/occupancy_map.h"

namespace rack::components {

class LadarSim final : public DataComponent<interfaces::LadarData> {
 public:
  LadarSim();

 protected:
  void init() override;
  HookResult on() override;
  HookResult loop() override;  // RT, periodic

 private:
  Parameter& map_;
  // Declared inputs: the chassis (every sample; no true pose for silence_ms: ERROR) and,
  // in 3-D, the drive.
  InputOf<interfaces::ChassisData>& chassis_;
  Parameter& mount_x_;
  Parameter& mount_y_;
  Parameter& mount_phi_;
  Parameter& beams_;
  Parameter& fov_deg_;
  Parameter& range_min_;
  Parameter& range_max_;
  Parameter& noise_sigma_;
  Parameter& seed_;
  InputOf<interfaces::ServoDriveData>& servo_;
  Parameter& scan_mode_;
  Parameter& mount_z_;
  Parameter& ceiling_height_;

  // 3-D: the range of one beam in the 2.5-D world (0: no echo).
  [[nodiscard]] double cast_3d(const Pose2d& robot, double theta, double bearing, double range_max) const noexcept;
  bool three_d_ = false;
  uint8_t mode_id_ = 0;
  TimeSeries<256> servo_angle_;

  std::optional<maps::OccupancyMap> map_data_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  interfaces::LadarData scan_{};
  Pose2d truth_;
  int64_t truth_time_ns_ = 0;
  int64_t published_time_ns_ = 0;
  int64_t last_truth_mono_ns_ = 0;  // when the last chassis sample arrived (monotonic)
  bool have_truth_ = false;
};

}  // namespace rack::components
