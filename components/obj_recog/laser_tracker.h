// Tracks objects in 2-D laser scans: the points of a Scan2D scan are cut into
// clusters (neighbouring beams closer than cluster_gap), clusters small enough to be
// an object (at most cluster_max_size across, at least cluster_min_points) are
// associated with tracks by nearest neighbour inside a gate, and each track runs a
// constant-velocity Kalman filter per axis in the odometry frame, so that the robot's
// own motion is not mistaken for the object's. A track is confirmed after
// confirm_hits associations, dropped after max_missed scans without one, and dynamic
// when confirmed and faster than dynamic_min_speed.
//
// Used by Scan2D (marks the points of dynamic clusters kScanPointDynObstacle, for the
// pilot) and ObjRecogLaser (publishes the tracks as an object list).
//
// Real-time contract: everything is RT-safe (fixed capacities, no allocation); one
// thread per tracker.
#pragma once

#include <array>
#include <cstdint>

#include "common/pose2d.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

struct TrackerOptions {
  double cluster_gap = 0.25;  // m, neighbouring points closer than this are one cluster
  uint32_t cluster_min_points = 3;
  double cluster_max_size = 1.0;  // m, larger clusters (walls) are not objects
  double gate = 0.8;              // m, a cluster farther from a track's prediction is not it
  uint32_t confirm_hits = 3;
  uint32_t max_missed = 5;
  double accel_std = 2.0;           // m/s^2, process noise of the constant-velocity model
  double measurement_std = 0.05;    // m, cluster centre noise
  double dynamic_min_speed = 0.25;  // m/s
};

class LaserTracker {
 public:
  static constexpr uint32_t kMaxClusters = 128;
  static constexpr uint32_t kMaxTracks = 64;

  struct Cluster {
    uint32_t first = 0, last = 0;  // point indices in the scan (inclusive; may include max-range points between)
    uint32_t points = 0;
    double x = 0, y = 0;            // centre, odometry frame
    double rx = 0, ry = 0;          // centre, robot frame
    double size_x = 0, size_y = 0;  // robot-frame bounding box
    int track = -1;                 // index into tracks(), -1: none
    bool object = false;            // small enough to track
  };
  struct Track {
    uint32_t id = 0;
    double x = 0, vx = 0, y = 0, vy = 0;  // odometry frame
    double pxx[4] = {}, pyy[4] = {};      // 2x2 covariances per axis (row-major)
    uint32_t hits = 0, missed = 0;
    double size_x = 0, size_y = 0;
    int64_t time_ns = 0;
    bool confirmed = false;
    [[nodiscard]] double speed() const noexcept;
  };

  void set_options(const TrackerOptions& o) noexcept { options_ = o; }
  [[nodiscard]] const TrackerOptions& options() const noexcept { return options_; }
  void reset() noexcept;
  // One scan taken at time_ns with the robot at `robot` in the odometry frame (use a
  // zero pose without odometry: then a moving robot makes the world seem to move).
  void update(const interfaces::Scan2dData& scan, const Pose2d& robot, int64_t time_ns) noexcept;
  // Marks the points of clusters whose track is dynamic as kScanPointDynObstacle.
  // Returns the number of points marked.
  uint32_t mark_dynamic(interfaces::Scan2dData& scan) const noexcept;

  [[nodiscard]] uint32_t cluster_count() const noexcept { return cluster_count_; }
  [[nodiscard]] const Cluster& cluster(uint32_t i) const noexcept { return clusters_[i]; }
  [[nodiscard]] uint32_t track_count() const noexcept { return track_count_; }
  [[nodiscard]] const Track& track(uint32_t i) const noexcept { return tracks_[i]; }
  [[nodiscard]] bool is_dynamic(const Track& t) const noexcept {
    return t.confirmed && t.speed() >= options_.dynamic_min_speed;
  }
  [[nodiscard]] const Pose2d& robot_pose() const noexcept { return robot_; }

 private:
  void cluster_scan(const interfaces::Scan2dData& scan) noexcept;
  void predict(Track& t, double dt) const noexcept;
  void correct(Track& t, double zx, double zy) const noexcept;

  TrackerOptions options_;
  std::array<Cluster, kMaxClusters> clusters_{};
  uint32_t cluster_count_ = 0;
  std::array<Track, kMaxTracks> tracks_{};
  uint32_t track_count_ = 0;
  uint32_t next_id_ = 1;
  Pose2d robot_;
};

}  // namespace rack::components
