// Generator's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the
// sample type it publishes and its class commands, as tools learn them from its class
// description. The payload struct is rack/interfaces/demo.h's (Monitor and the tests
// decode it); RESET is declared here (only tools send it).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/demo.h"

// Its class command (namespace rack::interfaces, as the data type's).
namespace rack::interfaces {

inline constexpr int8_t kGeneratorReset = 21;  // request, no body: counter to 0; reply OK

}  // namespace rack::interfaces

namespace rack::components {

inline constexpr DataTypeInfo kGeneratorType = data_type_info<interfaces::GeneratorData>("GeneratorData");
inline constexpr CommandInfo kGeneratorCommands[] = {
    {"RESET", interfaces::kGeneratorReset, nullptr, "the counter to 0"}};

}  // namespace rack::components
