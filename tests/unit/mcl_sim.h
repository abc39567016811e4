// A scripted robot for the MCL tests and bench: drives through waypoints in an
// occupancy map, synthesises laser scans by ray casting the map (OccupancyMap::cast_ray)
// with Gaussian range noise, and integrates noisy odometry. Deterministic per seed.
//
// Test and bench code; nothing here is RT-safe.
#pragma once

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "rack/maps/occupancy_map.h"

namespace rack::test {

struct SimPose {
  double x = 0.0, y = 0.0, phi = 0.0;
};

struct SimScan {
  // Robot-frame points of beams with an echo (what Scan2D gives MCL).
  std::vector<float> xs, ys;
  // The raw beams (for MRPT's own CObservation2DRangeScan in the bench): beam i at
  // start_angle + i * step, range or max_range (no echo: valid false).
  std::vector<float> ranges;
  std::vector<char> valid;
  float start_angle = 0.0F, step = 0.0F, max_range = 0.0F;
};

struct SimConfig {
  int beams = 181;                      // over the field of view
  double fov = 1.5 * std::numbers::pi;  // 270 degrees
  double max_range = 10.0;              // m
  double range_noise = 0.01;            // m (std dev)
  double step = 0.05;                   // m travelled between scans
  double turn_step = 0.15;              // rad turned at most between scans
  double odom_noise_xy = 0.02;          // relative (std dev per metre)
  double odom_noise_phi = 0.02;         // rad per rad + per metre
};

class ScriptedRobot {
 public:
  ScriptedRobot(const maps::OccupancyMap& map, SimConfig config, uint64_t seed) : map_(map), cfg_(config), rng_(seed) {}

  void place(const SimPose& p) {
    truth_ = p;
    odom_ = {0.0, 0.0, 0.0};
  }
  [[nodiscard]] const SimPose& truth() const noexcept { return truth_; }
  [[nodiscard]] const SimPose& odometry() const noexcept { return odom_; }

  // One step towards `goal`: turn (at most turn_step), then drive (at most `step`).
  // Returns true when the goal is reached (within half a step).
  bool step_towards(double gx, double gy) {
    const double dx = gx - truth_.x, dy = gy - truth_.y;
    const double dist = std::hypot(dx, dy);
    if (dist < cfg_.step * 0.5) return true;
    const double want = std::atan2(dy, dx);
    double turn = std::remainder(want - truth_.phi, 2 * std::numbers::pi);
    turn = std::clamp(turn, -cfg_.turn_step, cfg_.turn_step);
    const double fwd = std::fabs(turn) > 0.5 ? 0.0 : std::min(dist, cfg_.step);
    move(fwd, turn);
    return false;
  }

  // Truth moves by (forward, turn): turn half, drive, turn half. Odometry sees it
  // with noise.
  void move(double fwd, double turn) {
    auto apply = [](SimPose& p, double f, double t) {
      p.phi += t / 2;
      p.x += f * std::cos(p.phi);
      p.y += f * std::sin(p.phi);
      p.phi = std::remainder(p.phi + t / 2, 2 * std::numbers::pi);
    };
    apply(truth_, fwd, turn);
    std::normal_distribution<double> n(0.0, 1.0);
    const double f_odo = fwd * (1.0 + cfg_.odom_noise_xy * n(rng_));
    const double t_odo = turn + (std::fabs(turn) + std::fabs(fwd)) * cfg_.odom_noise_phi * n(rng_);
    apply(odom_, f_odo, t_odo);
  }

  // Teleports the truth (kidnapping); odometry does not notice.
  void kidnap(const SimPose& p) { truth_ = p; }

  SimScan scan() {
    SimScan s;
    s.start_angle = static_cast<float>(-cfg_.fov / 2);
    s.step = static_cast<float>(cfg_.fov / (cfg_.beams - 1));
    s.max_range = static_cast<float>(cfg_.max_range);
    std::normal_distribution<double> n(0.0, cfg_.range_noise);
    for (int i = 0; i < cfg_.beams; ++i) {
      const double a = s.start_angle + i * double{s.step};
      const maps::RayHit hit = map_.cast_ray(truth_.x, truth_.y, truth_.phi + a, cfg_.max_range);
      if (!hit.hit) {
        s.ranges.push_back(s.max_range);
        s.valid.push_back(0);
        continue;
      }
      const double r = std::max(0.01, hit.range + n(rng_));
      s.ranges.push_back(static_cast<float>(r));
      s.valid.push_back(1);
      s.xs.push_back(static_cast<float>(r * std::cos(a)));
      s.ys.push_back(static_cast<float>(r * std::sin(a)));
    }
    return s;
  }

 private:
  const maps::OccupancyMap& map_;
  SimConfig cfg_;
  std::mt19937_64 rng_;
  SimPose truth_{}, odom_{};
};

inline double angle_diff(double a, double b) { return std::remainder(a - b, 2 * std::numbers::pi); }

}  // namespace rack::test
