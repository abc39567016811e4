// The interface of the demo producer: Generator's sample, which Monitor (and many
// tests) read. Generator's RESET and the types of Monitor, Probe and ModeSwitchDemo
// are declared in their folders. Like every interface header: plain payload types, no
// heavy includes, so tools can decode the data.
//
// Real-time contract: plain data; RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/tims/payload.h"

namespace rack::interfaces {

// Generator: a periodic sine wave with a sample counter.
struct GeneratorData {
  double value = 0.0;   // amplitude * sin(2 pi f t) + offset
  int64_t counter = 0;  // samples since the last ON (or RESET)
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(GeneratorData, value), RACK_FIELD(GeneratorData, counter)};
  }
};
}  // namespace rack::interfaces
