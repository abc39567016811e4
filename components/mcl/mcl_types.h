// MCL's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (rack/interfaces/robot.h's MclData: the evaluators and rack-gui
// read it) and its class commands.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

inline constexpr FieldUnit kMclUnits[] = {
    {"x", "m"},          {"y", "m"},          {"phi", "rad"},         {"scan_time_ns", "ns"},
    {"particle_x", "m"}, {"particle_y", "m"}, {"particle_phi", "rad"}};
inline constexpr DataTypeInfo kMclType = data_type_info<interfaces::MclData>("MclData", {}, kMclUnits);
inline constexpr DataTypeInfo kMclInitBody = data_type_info<interfaces::MclInit>("MclInit");
inline constexpr CommandInfo kMclCommands[] = {
    {"INIT", interfaces::kMclInit, &kMclInitBody,
     "re-initialise around x, y, phi with sigma_xy (m), sigma_phi (rad); global=1: everywhere"}};

}  // namespace rack::components
