// Pilot's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (rack/interfaces/navigation.h's PilotData) with the names of its
// mode and status values, and its class commands.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/navigation.h"

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
