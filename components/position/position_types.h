// Position's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the
// sample type it publishes (rack/interfaces/robot.h's PositionData: the Pilot, Scan3D
// and the evaluators read it) and its class commands.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

inline constexpr FieldUnit kPositionUnits[] = {{"x", "m"},
                                               {"y", "m"},
                                               {"phi", "rad"},
                                               {"var_x", "m^2"},
                                               {"var_y", "m^2"},
                                               {"var_phi", "rad^2"},
                                               {"reference_time_ns", "ns"}};
inline constexpr DataTypeInfo kPositionType = data_type_info<interfaces::PositionData>("PositionData", {},
                                                                                       kPositionUnits);
inline constexpr DataTypeInfo kPositionUpdateBody = data_type_info<interfaces::PositionUpdate>("PositionUpdate");
inline constexpr CommandInfo kPositionCommands[] = {
    {"UPDATE", interfaces::kPositionUpdate, &kPositionUpdateBody, "the robot was at x, y, phi at time_ns (host time)"}};

}  // namespace rack::components
