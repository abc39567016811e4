// Pilot's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (PilotData) with the names of its mode and status values, and its
// class commands with their bodies. No other class reads them. Conventions as in
// rack/interfaces/robot.h.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/tims/payload.h"

// The payload types (namespace rack::interfaces, as every sample type's, so that code
// naming them did not change when they moved here from components/interfaces).
namespace rack::interfaces {

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

namespace rack::components {

namespace pilot_names {
constexpr uint32_t u(interfaces::PilotMode m) { return static_cast<uint32_t>(m); }
constexpr uint32_t u(interfaces::PilotStatus s) { return static_cast<uint32_t>(s); }
using interfaces::PilotMode;
using interfaces::PilotStatus;
inline constexpr ValueName kMode[] = {{u(PilotMode::kHold), "HOLD"},
                                      {u(PilotMode::kFollowPath), "FOLLOW_PATH"},
                                      {u(PilotMode::kDestination), "DESTINATION"}};
inline constexpr ValueName kStatus[] = {{u(PilotStatus::kIdle), "IDLE"},
                                        {u(PilotStatus::kDriving), "DRIVING"},
                                        {u(PilotStatus::kReached), "REACHED"},
                                        {u(PilotStatus::kBlocked), "BLOCKED"},
                                        {u(PilotStatus::kNoPath), "NO_PATH"},
                                        {u(PilotStatus::kPreempted), "PREEMPTED"},
                                        {u(PilotStatus::kNoInput), "NO_INPUT"},
                                        {u(PilotStatus::kPlanning), "PLANNING"},
                                        {u(PilotStatus::kUnreachable), "UNREACHABLE"}};
}  // namespace pilot_names

inline constexpr FieldValueNames kPilotNames[] = {{"mode", pilot_names::kMode}, {"status", pilot_names::kStatus}};
inline constexpr FieldUnit kPilotUnits[] = {{"target_x", "m"},     {"target_y", "m"},   {"pose_x", "m"},
                                            {"pose_y", "m"},       {"pose_phi", "rad"}, {"distance_to_target", "m"},
                                            {"vx", "m/s"},         {"omega", "rad/s"},  {"obstacle_distance", "m"},
                                            {"speed_limit", "m/s"}};
inline constexpr DataTypeInfo kPilotType = data_type_info<interfaces::PilotData>("PilotData", kPilotNames, kPilotUnits);
inline constexpr DataTypeInfo kPilotDestinationBody = data_type_info<interfaces::PilotDestination>("PilotDestination");
inline constexpr CommandInfo kPilotCommands[] = {
    {"SET_DESTINATION", interfaces::kPilotSetDestination, &kPilotDestinationBody, "drive straight to x, y (m)"},
    {"FOLLOW_PATH", interfaces::kPilotFollowPath, nullptr, "follow the Path component's path"},
    {"HOLD", interfaces::kPilotHold, nullptr, "stop and stand"}};

}  // namespace rack::components
