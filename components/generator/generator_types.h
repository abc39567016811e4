// Generator's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the
// sample type it publishes and its class commands, as tools learn them from its class
// description. The payload struct is rack/interfaces/demo.h's (Monitor and the tests
// decode it).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

inline constexpr DataTypeInfo kGeneratorType = data_type_info<interfaces::GeneratorData>("GeneratorData");
inline constexpr CommandInfo kGeneratorCommands[] = {
    {"RESET", interfaces::kGeneratorReset, nullptr, "the counter to 0"}};

}  // namespace rack::components
