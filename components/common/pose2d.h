// 2-D rigid-body poses for the robot classes (private to components/).
//
// compose(a, b): b expressed in a's frame, taken to a's parent frame (a (+) b).
// between(a, b): the pose of b in a's frame (a^-1 (+) b), so compose(a, between(a, b)) == b.
//
// Real-time contract: everything here is RT-safe (no allocation, no exceptions).
#pragma once

#include <cmath>
#include <numbers>

namespace rack::components {

struct Pose2d {
  double x = 0.0;
  double y = 0.0;
  double phi = 0.0;
};

// Into (-pi, pi].
[[nodiscard]] inline double normalize_angle(double a) noexcept {
  if (!std::isfinite(a)) return 0.0;
  a = std::remainder(a, 2.0 * std::numbers::pi);  // [-pi, pi]
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

[[nodiscard]] inline Pose2d compose(const Pose2d& a, const Pose2d& b) noexcept {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  return Pose2d{a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, normalize_angle(a.phi + b.phi)};
}

[[nodiscard]] inline Pose2d between(const Pose2d& a, const Pose2d& b) noexcept {
  const double c = std::cos(a.phi);
  const double s = std::sin(a.phi);
  const double dx = b.x - a.x;
  const double dy = b.y - a.y;
  return Pose2d{c * dx + s * dy, -s * dx + c * dy, normalize_angle(b.phi - a.phi)};
}

// The motion of a robot driving at (vx, vy, omega) in its own frame for dt seconds,
// as a pose in its starting frame (exact for constant velocities: an arc).
[[nodiscard]] inline Pose2d integrate_twist(double vx, double vy, double omega, double dt) noexcept {
  const double dphi = omega * dt;
  double a = 1.0;  // sin(dphi)/dphi
  double b = 0.0;  // (1 - cos(dphi))/dphi
  if (std::abs(dphi) > 1e-9) {
    a = std::sin(dphi) / dphi;
    b = (1.0 - std::cos(dphi)) / dphi;
  } else {
    b = dphi / 2.0;
  }
  const double dx = vx * dt;
  const double dy = vy * dt;
  return Pose2d{a * dx - b * dy, b * dx + a * dy, dphi};
}

}  // namespace rack::components
