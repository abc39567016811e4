// Data types and class commands of RACK's navigation classes: Path (a smooth path
// through waypoints) and Pilot (drives the chassis along a path or to a destination).
// Conventions as in rack/interfaces/robot.h: SI units, map frame, 2-D poses, plain
// fixed-size payloads with a field table.
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

// ---------------------------------------------------------------------------
// Pilot (class Pilot): pure-pursuit control on the Position estimate, with the speed
// limited by the nearest obstacle in the Scan2D data. Published every cycle.
enum class PilotMode : uint8_t {
  kHold = 0,         // standing (HOLD, or nothing to do)
  kFollowPath = 1,   // following the Path component's path
  kDestination = 2,  // driving to a destination (SET_DESTINATION)
};
enum class PilotStatus : uint8_t {
  kIdle = 0,  // holding
  kDriving = 1,
  kReached = 2,      // at the destination / end of an open path
  kBlocked = 3,      // an obstacle inside the safety margin: standing until it is gone
  kNoPath = 4,       // following, but the Path has not published a path
  kPreempted = 5,    // the chassis refused MOVE (another pilot took over): standing
  kNoInput = 6,      // no recent Position (or Scan2D) data: standing
  kPlanning = 7,     // waiting for the planned way to the destination (a cycle or two)
  kUnreachable = 8,  // no way to the destination on the map (GDOS and SET_DESTINATION say why): holding
};
struct PilotData {
  double target_x = 0.0;  // the destination (or the path's last point)
  double target_y = 0.0;
  double pose_x = 0.0;  // the Position estimate the command was computed on
  double pose_y = 0.0;
  double pose_phi = 0.0;
  double distance_to_target = 0.0;  // m, straight line
  double vx = 0.0;                  // m/s, commanded
  double omega = 0.0;               // rad/s, commanded
  double obstacle_distance = 0.0;   // m, free space ahead of the outline (max range when none)
  double speed_limit = 0.0;         // m/s, what the obstacle allowed this cycle
  uint32_t path_index = 0;          // progress along the path's points
  uint32_t laps = 0;                // completed rounds of a closed path
  uint32_t moves_refused = 0;       // MOVEs the chassis answered ERROR
  uint32_t blocked_cycles = 0;      // cycles spent in kBlocked since ON
  uint32_t bad_destinations = 0;    // `destination` texts that were not "x,y" (ignored)
  uint8_t mode = 0;                 // PilotMode
  uint8_t status = 0;               // PilotStatus
  uint8_t pad_[2] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(PilotData, target_x),
                      RACK_FIELD(PilotData, target_y),
                      RACK_FIELD(PilotData, pose_x),
                      RACK_FIELD(PilotData, pose_y),
                      RACK_FIELD(PilotData, pose_phi),
                      RACK_FIELD(PilotData, distance_to_target),
                      RACK_FIELD(PilotData, vx),
                      RACK_FIELD(PilotData, omega),
                      RACK_FIELD(PilotData, obstacle_distance),
                      RACK_FIELD(PilotData, speed_limit),
                      RACK_FIELD(PilotData, path_index),
                      RACK_FIELD(PilotData, laps),
                      RACK_FIELD(PilotData, moves_refused),
                      RACK_FIELD(PilotData, blocked_cycles),
                      RACK_FIELD(PilotData, bad_destinations),
                      RACK_FIELD(PilotData, mode),
                      RACK_FIELD(PilotData, status)};
  }
};
// SET_DESTINATION (request): drive to (x, y): along a planned way when the Pilot has a
// `map`, else straight (the Scan2D speed limit stops it before obstacles). Reply OK, or
// ERROR with the reason when the planner finds no way there.
inline constexpr int8_t kPilotSetDestination = 21;
struct PilotDestination {
  double x = 0.0;
  double y = 0.0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(PilotDestination, x), RACK_FIELD(PilotDestination, y)};
  }
};
// FOLLOW_PATH (request, no body): follow the Path component's path from the point
// nearest the robot. Reply OK.
inline constexpr int8_t kPilotFollowPath = 22;
// HOLD (request, no body): stop and stand (stays ENABLED and the active pilot). Reply OK.
inline constexpr int8_t kPilotHold = 23;

}  // namespace rack::interfaces
