// Path's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (rack/interfaces/navigation.h's PathData: the Pilot reads it) and
// its class commands.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/navigation.h"

namespace rack::components {

inline constexpr FieldUnit kPathUnits[] = {
    {"length", "m"}, {"waypoint_x", "m"}, {"waypoint_y", "m"}, {"x", "m"}, {"y", "m"}};
inline constexpr DataTypeInfo kPathType = data_type_info<interfaces::PathData>("PathData", {}, kPathUnits);
inline constexpr DataTypeInfo kPathMakeBody = data_type_info<interfaces::PathMake>("PathMake");
inline constexpr CommandInfo kPathCommands[] = {
    {"MAKE", interfaces::kPathMake, &kPathMakeBody,
     "a path through count waypoints x=.., y=.. (comma lists); no fields: the parameter"}};

}  // namespace rack::components
