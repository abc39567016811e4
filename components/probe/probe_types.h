// Probe's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (ProbeData) and its class commands.
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

// Probe: counts of its hook calls, so tests see the life cycle from outside.
struct ProbeData {
  int64_t loops = 0;
  int64_t on_calls = 0;
  int64_t off_calls = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ProbeData, loops), RACK_FIELD(ProbeData, on_calls), RACK_FIELD(ProbeData, off_calls)};
  }
};
inline constexpr int8_t kProbeEcho = 21;   // request with an 8-byte body; replied OK with the same body
inline constexpr int8_t kProbeThrow = 22;  // request: command() throws (the component goes to ERROR)

}  // namespace rack::interfaces

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
