#include "obj_recog/laser_tracker.h"

#include <algorithm>
#include <cmath>

namespace rack::components {

using interfaces::Scan2dData;

double LaserTracker::Track::speed() const noexcept { return std::hypot(vx, vy); }

void LaserTracker::reset() noexcept {
  cluster_count_ = 0;
  track_count_ = 0;
}

void LaserTracker::cluster_scan(const Scan2dData& scan) noexcept {
  cluster_count_ = 0;
  const uint32_t n = std::min(scan.point_count, interfaces::kScan2dMaxPoints);
  const double c = std::cos(robot_.phi), s = std::sin(robot_.phi);
  Cluster* cur = nullptr;
  double px = 0, py = 0;  // previous valid point
  double min_x = 0, max_x = 0, min_y = 0, max_y = 0, sum_x = 0, sum_y = 0;
  const auto close = [&]() {
    if (cur == nullptr) return;
    cur->rx = sum_x / cur->points;
    cur->ry = sum_y / cur->points;
    cur->x = robot_.x + c * cur->rx - s * cur->ry;
    cur->y = robot_.y + s * cur->rx + c * cur->ry;
    cur->size_x = max_x - min_x;
    cur->size_y = max_y - min_y;
    cur->object = cur->points >= options_.cluster_min_points &&
                  std::hypot(cur->size_x, cur->size_y) <= options_.cluster_max_size;
    cur = nullptr;
  };
  for (uint32_t i = 0; i < n; ++i) {
    if (scan.type[i] == interfaces::kScanPointMaxRange) continue;
    const double x = scan.x[i], y = scan.y[i];
    if (!std::isfinite(x) || !std::isfinite(y)) continue;
    if (cur != nullptr && std::hypot(x - px, y - py) > options_.cluster_gap) close();
    if (cur == nullptr) {
      if (cluster_count_ == kMaxClusters) break;  // the rest of the scan is left unclustered
      cur = &clusters_[cluster_count_++];
      *cur = Cluster{};
      cur->first = i;
      min_x = max_x = x;
      min_y = max_y = y;
      sum_x = sum_y = 0;
    }
    cur->last = i;
    ++cur->points;
    sum_x += x;
    sum_y += y;
    min_x = std::min(min_x, x);
    max_x = std::max(max_x, x);
    min_y = std::min(min_y, y);
    max_y = std::max(max_y, y);
    px = x;
    py = y;
  }
  close();
}

void LaserTracker::predict(Track& t, double dt) const noexcept {
  const double q = options_.accel_std * options_.accel_std;
  const double q11 = q * dt * dt * dt * dt / 4.0, q12 = q * dt * dt * dt / 2.0, q22 = q * dt * dt;
  const auto axis = [&](double& p, double& v, double* cov) {
    p += v * dt;
    // cov = F cov F' + Q with F = [1 dt; 0 1] (cov: this axis' 2x2 covariance P).
    const double a = cov[0], b = cov[1], d = cov[3];
    cov[0] = a + 2.0 * dt * b + dt * dt * d + q11;
    cov[1] = b + dt * d + q12;
    cov[2] = cov[1];
    cov[3] = d + q22;
  };
  axis(t.x, t.vx, t.pxx);
  axis(t.y, t.vy, t.pyy);
}

void LaserTracker::correct(Track& t, double zx, double zy) const noexcept {
  const double r = options_.measurement_std * options_.measurement_std;
  const auto axis = [&](double& p, double& v, double* cov, double z) {
    const double s = cov[0] + r;
    const double k0 = cov[0] / s, k1 = cov[2] / s;
    const double innov = z - p;
    p += k0 * innov;
    v += k1 * innov;
    const double a = cov[0], b = cov[1], d = cov[3];
    cov[0] = (1.0 - k0) * a;
    cov[1] = (1.0 - k0) * b;
    cov[2] = cov[1];
    cov[3] = d - k1 * b;
  };
  axis(t.x, t.vx, t.pxx, zx);
  axis(t.y, t.vy, t.pyy, zy);
}

void LaserTracker::update(const Scan2dData& scan, const Pose2d& robot, int64_t time_ns) noexcept {
  robot_ = robot;
  cluster_scan(scan);
  // Predict every track to this scan's time.
  for (uint32_t k = 0; k < track_count_; ++k) {
    Track& t = tracks_[k];
    const double dt = std::clamp(static_cast<double>(time_ns - t.time_ns) * 1e-9, 0.0, 5.0);
    predict(t, dt);
    t.time_ns = time_ns;
  }
  // Greedy nearest-neighbour association: repeatedly take the closest free pair.
  bool track_used[kMaxTracks] = {};
  for (;;) {
    double best = options_.gate;
    int bc = -1, bt = -1;
    for (uint32_t i = 0; i < cluster_count_; ++i) {
      const Cluster& c = clusters_[i];
      if (!c.object || c.track >= 0) continue;
      for (uint32_t k = 0; k < track_count_; ++k) {
        if (track_used[k]) continue;
        const double d = std::hypot(c.x - tracks_[k].x, c.y - tracks_[k].y);
        if (d < best) {
          best = d;
          bc = static_cast<int>(i);
          bt = static_cast<int>(k);
        }
      }
    }
    if (bc < 0) break;
    Cluster& c = clusters_[static_cast<uint32_t>(bc)];
    Track& t = tracks_[static_cast<uint32_t>(bt)];
    correct(t, c.x, c.y);
    t.size_x = c.size_x;
    t.size_y = c.size_y;
    ++t.hits;
    t.missed = 0;
    if (t.hits >= options_.confirm_hits) t.confirmed = true;
    c.track = bt;
    track_used[bt] = true;
  }
  // Tracks without a cluster this time: missed; too many misses: dropped (compacting,
  // with the clusters' track indices moved along).
  int remap[kMaxTracks];
  uint32_t kept = 0;
  for (uint32_t k = 0; k < track_count_; ++k) {
    if (!track_used[k]) ++tracks_[k].missed;
    if (tracks_[k].missed > options_.max_missed) {
      remap[k] = -1;
      continue;
    }
    remap[k] = static_cast<int>(kept);
    if (kept != k) tracks_[kept] = tracks_[k];
    ++kept;
  }
  track_count_ = kept;
  for (uint32_t i = 0; i < cluster_count_; ++i) {
    if (clusters_[i].track >= 0) clusters_[i].track = remap[clusters_[i].track];
  }
  // New tracks for the objects nobody claimed.
  const double r = options_.measurement_std * options_.measurement_std;
  for (uint32_t i = 0; i < cluster_count_ && track_count_ < kMaxTracks; ++i) {
    Cluster& c = clusters_[i];
    if (!c.object || c.track >= 0) continue;
    Track& t = tracks_[track_count_];
    t = Track{};
    t.id = next_id_++;
    t.x = c.x;
    t.y = c.y;
    t.pxx[0] = t.pyy[0] = r;
    t.pxx[3] = t.pyy[3] = 4.0;  // (2 m/s)^2: the speed is unknown at first
    t.hits = 1;
    t.size_x = c.size_x;
    t.size_y = c.size_y;
    t.time_ns = time_ns;
    t.confirmed = options_.confirm_hits <= 1;
    c.track = static_cast<int>(track_count_);
    ++track_count_;
  }
}

uint32_t LaserTracker::mark_dynamic(Scan2dData& scan) const noexcept {
  uint32_t marked = 0;
  for (uint32_t i = 0; i < cluster_count_; ++i) {
    const Cluster& c = clusters_[i];
    if (c.track < 0 || !is_dynamic(tracks_[static_cast<uint32_t>(c.track)])) continue;
    for (uint32_t p = c.first; p <= c.last && p < scan.point_count; ++p) {
      if (scan.type[p] == interfaces::kScanPointMaxRange) continue;
      scan.type[p] = interfaces::kScanPointDynObstacle;
      ++marked;
    }
  }
  return marked;
}

}  // namespace rack::components
