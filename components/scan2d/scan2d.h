// Scan2D (class Scan2D): a Ladar's scans as points in the robot frame. Triggered by
// the ladar's samples (getContData, cascading ON). Per beam: an optional median
// filter over the neighbouring valid ranges (removes single-beam outliers: dust,
// mixed pixels), the range window [range_min, range_max], the mounting offset
// (mount_x, mount_y, mount_phi: the sensor's pose in the robot frame). Beams without
// an echo become max-range points (type kScanPointMaxRange) or are left out.
//
// With an `odometry` component configured, each scan carries the odometry at the
// scan's time, so localisation need not look it up. Scan2D subscribes to every
// odometry sample (a PoseSeries of the last 512) and holds a scan (up to 8) until
// odometry at or after the scan's time has arrived, then interpolates between the
// two samples around it: never extrapolated, so a scan never sees odometry from
// before its own time, whatever order or delay the two streams arrive with (a
// replay at any speed gives the same odometry). A held scan goes out without
// odometry (odometry_valid 0, counted as missing) only when no such sample came
// within odometry_wait_ms of the scan's arrival, when the hold queue is full, or
// when the scan is older than the oldest pose kept. Live, the hold costs at most
// one odometry period of latency.
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

#include <atomic>
#include <cstdint>
#include <memory>

#include "common/pose_series.h"
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

  // How the scans published since ON got their odometry (any thread; relaxed).
  struct OdometryCounts {
    uint64_t interpolated = 0;  // between the two samples around the scan's time (or at one)
    uint64_t missing = 0;       // published without odometry (see the class comment)
  };
  [[nodiscard]] OdometryCounts odometry_counts() const noexcept;
  void describe_status(std::string& out) const override;  // not RT (rackd's main thread)

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, triggered by LadarData and OdometryData

 private:
  static constexpr std::size_t kHeld = 8;  // scans waiting for their odometry
  void take(const InputPort& from) noexcept;
  // Publishes the held scans whose odometry is there (or will never come); `flush`:
  // all of them, without odometry where none is there.
  void release(bool flush) noexcept;
  void convert_and_publish(const interfaces::LadarData& ladar, int64_t time_ns) noexcept;

  // Declared in this order: the odometry is subscribed first (every sample from
  // before the first scan on).
  InputOf<interfaces::OdometryData>& odometry_;
  InputOf<interfaces::LadarData>& ladar_;
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
  Parameter& odometry_wait_ms_;
  LaserTracker tracker_;           // data task
  interfaces::Scan2dData scan_{};  // data task
  // Data task: the odometry poses, the held scans (a ring of kHeld) with their times
  // and host arrival times.
  PoseSeries<512> poses_;
  std::unique_ptr<interfaces::LadarData[]> held_;
  int64_t held_time_ns_[kHeld] = {};
  int64_t held_arrival_ns_[kHeld] = {};
  std::size_t held_head_ = 0, held_count_ = 0;
  bool use_odometry_ = false;
  // Relaxed counters: each on its own, read by status and tests.
  std::atomic<uint64_t> odometry_interpolated_{0}, odometry_missing_{0};
};

}  // namespace rack::components
