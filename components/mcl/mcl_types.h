// MCL's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (rack/interfaces/robot.h's MclData: the evaluators read it) and its
// class commands with their bodies (INIT's MclInit, declared here: only tools send it).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/robot.h"

// Its class command (namespace rack::interfaces, as the data type's).
namespace rack::interfaces {

// INIT (request): re-initialise the filter around a pose with a spread (global = 1:
// spread over the whole free space, the pose is ignored). Reply OK.
inline constexpr int8_t kMclInit = 21;
struct MclInit {
  double x = 0.0;
  double y = 0.0;
  double phi = 0.0;
  double sigma_xy = 0.0;   // m
  double sigma_phi = 0.0;  // rad
  uint8_t global = 0;
  uint8_t pad_[7] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(MclInit, x),        RACK_FIELD(MclInit, y),         RACK_FIELD(MclInit, phi),
                      RACK_FIELD(MclInit, sigma_xy), RACK_FIELD(MclInit, sigma_phi), RACK_FIELD(MclInit, global)};
  }
};

}  // namespace rack::interfaces

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
