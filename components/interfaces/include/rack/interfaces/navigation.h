// The interface of RACK's Path class (a smooth path through waypoints): its data,
// which Pilot follows, and MAKE, which Pilot sends to it. Pilot's own types are in
// components/pilot/pilot_types.h. Conventions as in rack/interfaces/robot.h: SI units,
// map frame, 2-D poses, plain fixed-size payloads with a field table.
//
// Real-time contract: plain data; everything here is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/tims/payload.h"

namespace rack::interfaces {

// ---------------------------------------------------------------------------
// Path (class Path): a path through waypoints (a centripetal Catmull-Rom spline,
// which passes through every waypoint without loops or cusps), sampled every
// `resolution` metres. Published whenever it is (re)made.
inline constexpr uint32_t kPathMaxWaypoints = 32;
inline constexpr uint32_t kPathMaxPoints = 2048;
struct PathData {
  uint32_t waypoint_count = 0;
  uint32_t point_count = 0;
  uint32_t makes = 0;     // paths made since ON
  uint32_t rejected = 0;  // waypoint sets rejected (malformed) since ON
  double length = 0.0;    // m, along the sampled points
  uint8_t closed = 0;     // 1: the last point joins the first (a loop to drive round)
  uint8_t pad_[7] = {};
  char last_error[96] = {};  // why the last rejected waypoint set was rejected
  float waypoint_x[kPathMaxWaypoints] = {};
  float waypoint_y[kPathMaxWaypoints] = {};
  float x[kPathMaxPoints] = {};  // m, map frame
  float y[kPathMaxPoints] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(PathData, waypoint_count),
                      RACK_FIELD(PathData, point_count),
                      RACK_FIELD(PathData, makes),
                      RACK_FIELD(PathData, rejected),
                      RACK_FIELD(PathData, length),
                      RACK_FIELD(PathData, closed),
                      RACK_FIELD(PathData, last_error),
                      RACK_FIELD(PathData, waypoint_x),
                      RACK_FIELD(PathData, waypoint_y),
                      RACK_FIELD(PathData, x),
                      RACK_FIELD(PathData, y)};
  }
};
// MAKE (request): make a path through these waypoints and publish it. An empty body
// re-reads the `waypoints` parameter. Reply OK, or ERROR with the reason (fewer than
// two waypoints, too many, not finite, two equal neighbours, too long to sample).
inline constexpr int8_t kPathMake = 21;
struct PathMake {
  uint32_t count = 0;
  uint8_t closed = 0;
  uint8_t pad_[3] = {};
  double x[kPathMaxWaypoints] = {};
  double y[kPathMaxWaypoints] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(PathMake, count), RACK_FIELD(PathMake, closed), RACK_FIELD(PathMake, x),
                      RACK_FIELD(PathMake, y)};
  }
};

}  // namespace rack::interfaces
