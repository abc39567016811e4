// Probe's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (rack/interfaces/demo.h's ProbeData) and its class commands.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

struct ProbeEchoBody {  // ECHO's 8-byte body, replied as it came
  int64_t value = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(ProbeEchoBody, value)}; }
};

inline constexpr DataTypeInfo kProbeType = data_type_info<interfaces::ProbeData>("ProbeData");
inline constexpr DataTypeInfo kProbeEchoBody = data_type_info<ProbeEchoBody>("Int64");
inline constexpr CommandInfo kProbeCommands[] = {
    {"ECHO", interfaces::kProbeEcho, &kProbeEchoBody, "replies OK with the same body"},
    {"THROW", interfaces::kProbeThrow, nullptr, "command() throws: the component goes to ERROR"}};

}  // namespace rack::components
