// The free distance ahead of the robot in its driving corridor, from a Scan2D scan
// (points in the robot frame) or a Ladar scan (assumed at the robot's origin, looking
// ahead). Used by the joystick pilot to slow down before obstacles.
//
// Real-time contract: RT-safe (arithmetic over the scan).
#pragma once

#include <cmath>
#include <limits>

#include "rack/interfaces/robot.h"

namespace rack::components::obstacle {

// Corridor: |y| <= half_width; the robot's front is at x = front. Returns the
// distance from the front to the nearest point ahead inside the corridor (>= 0), or
// +infinity when there is none.
inline double free_ahead(const interfaces::Scan2dData& s, double front, double half_width) noexcept {
  double best = std::numeric_limits<double>::infinity();
  const uint32_t n = s.point_count < interfaces::kScan2dMaxPoints ? s.point_count : interfaces::kScan2dMaxPoints;
  for (uint32_t i = 0; i < n; ++i) {
    if (s.type[i] == interfaces::kScanPointMaxRange) continue;  // no echo: nothing there
    const double x = s.x[i], y = s.y[i];
    if (x <= 0.0 || std::fabs(y) > half_width) continue;
    best = std::fmin(best, std::fmax(0.0, x - front));
  }
  return best;
}

inline double free_ahead(const interfaces::LadarData& s, double front, double half_width) noexcept {
  double best = std::numeric_limits<double>::infinity();
  const uint32_t n = s.beam_count < interfaces::kLadarMaxBeams ? s.beam_count : interfaces::kLadarMaxBeams;
  for (uint32_t i = 0; i < n; ++i) {
    const double r = s.range[i];
    if (!(r > 0.0) || (s.max_range > 0.0F && r > s.max_range)) continue;  // no echo
    const double a = s.start_angle + static_cast<double>(i) * s.angle_step;
    const double x = r * std::cos(a), y = r * std::sin(a);
    if (x <= 0.0 || std::fabs(y) > half_width) continue;
    best = std::fmin(best, std::fmax(0.0, x - front));
  }
  return best;
}

}  // namespace rack::components::obstacle
