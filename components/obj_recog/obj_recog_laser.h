// ObjRecogLaser (class ObjRecog): objects in a Scan2D component's scans, tracked over
// time (obj_recog/laser_tracker.h: clusters of neighbouring points, nearest-neighbour
// association, a constant-velocity Kalman filter per track in the odometry frame).
// Publishes, per scan, every confirmed track seen in it: id (stable while tracked),
// type kObjTypeLaserCluster, position and size in the robot frame at the scan's
// time, velocity over ground (odometry-compensated when the scans carry odometry)
// expressed in the robot frame, probability from the track's age.
//
// Bad input: an empty scan (no point) is skipped and counted in bad_input (the tracks
// coast; a scan with only max-range points is not empty: it shows free space). The
// Scan2D going silent for data_timeout puts the component in ERROR.
//
// Real-time contract: on(), off() and loop() are RT-safe.
#pragma once

#include "obj_recog/laser_tracker.h"
#include "rack/core/data_component.h"
#include "obj_recog_types.h"

namespace rack::components {

class ObjRecogLaser final : public DataComponent<interfaces::ObjRecogData> {
 public:
  ObjRecogLaser();

  // Fills `out` from the tracker's state after an update (pure, RT-safe).
  static void fill(const LaserTracker& tracker, interfaces::ObjRecogData& out) noexcept;

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, triggered by Scan2dData

 private:
  InputOf<interfaces::Scan2dData>& scan2d_;
  Parameter& cluster_gap_;
  Parameter& cluster_min_points_;
  Parameter& cluster_max_size_;
  Parameter& gate_;
  Parameter& confirm_hits_;
  Parameter& max_missed_;
  Parameter& accel_std_;
  Parameter& measurement_std_;
  Parameter& dynamic_min_speed_;
  LaserTracker tracker_;
  interfaces::ObjRecogData out_{};
};

}  // namespace rack::components
