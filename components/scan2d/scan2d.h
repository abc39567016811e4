// Scan2D (class Scan2D): a Ladar's scans as points in the robot frame. Triggered by
// the ladar's samples (getContData, cascading ON). Per beam: an optional median
// filter over the neighbouring valid ranges (removes single-beam outliers: dust,
// mixed pixels), the range window [range_min, range_max], the mounting offset
// (mount_x, mount_y, mount_phi: the sensor's pose in the robot frame). Beams without
// an echo become max-range points (type kScanPointMaxRange) or are left out.
//
// With an `odometry` component configured, each scan carries the odometry at the
// scan's time (GET_DATA by time, carried to the exact time with the sample's
// velocities), so localisation need not look it up.
//
// With `dynamic_objects`, Scan2D tracks small clusters of points over time
// (obj_recog/laser_tracker.h: nearest neighbour and a constant-velocity Kalman filter
// in the odometry frame) and marks the points of clusters that move faster than
// dynamic_min_speed as kScanPointDynObstacle, so the pilot sees them in the same
// scan. (ObjRecogLaser publishes the same tracks as an object list; the tracker runs
// here rather than there so that Scan2D does not depend on its own consumer.)
//
// Real-time contract: on(), off() and loop() are RT-safe; the scan is built in place.
#pragma once

#include <cstdint>

#include "obj_recog/laser_tracker.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Scan2d final : public DataComponent<interfaces::Scan2dData> {
 public:
  Scan2d();

  struct Geometry {
    double mount_x = 0.0, mount_y = 0.0, mount_phi = 0.0;
    double range_min = 0.0;
    double range_max = 0.0;  // 0: the ladar's own max_range
    int median = 1;          // odd window, 1: off
    bool keep_max_range = true;
  };
  // Converts one ladar scan (pure function, RT-safe): fills the points of `out`
  // (point_count, x, y, range, bearing, type, max_range, duration_ns).
  static void convert(const interfaces::LadarData& ladar, const Geometry& g, interfaces::Scan2dData& out) noexcept;

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT, triggered by LadarData

 private:
  void fill_odometry(int64_t time_ns) noexcept;

  Parameter& ladar_;
  Parameter& odometry_;
  Parameter& mount_x_;
  Parameter& mount_y_;
  Parameter& mount_phi_;
  Parameter& range_min_;
  Parameter& range_max_;
  Parameter& median_;
  Parameter& keep_max_range_;
  Parameter& dynamic_objects_;
  Parameter& dynamic_min_speed_;
  Parameter& cluster_gap_;
  Parameter& cluster_max_size_;
  LaserTracker tracker_;  // data task
  interfaces::LadarData ladar_data_{};  // data task
  interfaces::Scan2dData scan_{};       // data task
  uint64_t odometry_misses_ = 0;
};

}  // namespace rack::components
