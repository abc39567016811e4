// Odometry's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the
// sample type it publishes (rack/interfaces/robot.h's OdometryData: Position, Scan2D
// and Scan3D read it) and its class commands (RESET, declared here: only tools send it).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/robot.h"

// Its class command (namespace rack::interfaces, as the data type's).
namespace rack::interfaces {

// RESET (request, no body): the pose to zero. Reply OK.
inline constexpr int8_t kOdometryReset = 21;

}  // namespace rack::interfaces

namespace rack::components {

inline constexpr FieldUnit kOdometryUnits[] = {{"x", "m"},    {"y", "m"},         {"phi", "rad"},
                                               {"vx", "m/s"}, {"omega", "rad/s"}, {"distance", "m"}};
inline constexpr DataTypeInfo kOdometryType = data_type_info<interfaces::OdometryData>("OdometryData", {},
                                                                                       kOdometryUnits);
inline constexpr CommandInfo kOdometryCommands[] = {{"RESET", interfaces::kOdometryReset, nullptr, "the pose to zero"}};

}  // namespace rack::components
