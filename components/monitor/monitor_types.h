// Monitor's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (MonitorData). It reads Generator's (rack/interfaces/demo.h).
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

// Monitor: what a consumer saw of its source's stream.
struct MonitorData {
  uint64_t received = 0;  // samples received since ON
  uint64_t gaps = 0;      // samples missing from the stream (by sequence)
  uint64_t source_sequence = 0;
  double last_value = 0.0;  // the source's last value (Generator data)
  int64_t latency_ns = 0;   // receive time - recording time of the last sample
  int64_t latency_max_ns = 0;
  int64_t real_period_ns = 0;  // the period the source granted
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(MonitorData, received),        RACK_FIELD(MonitorData, gaps),
                      RACK_FIELD(MonitorData, source_sequence), RACK_FIELD(MonitorData, last_value),
                      RACK_FIELD(MonitorData, latency_ns),      RACK_FIELD(MonitorData, latency_max_ns),
                      RACK_FIELD(MonitorData, real_period_ns)};
  }
};

}  // namespace rack::interfaces

namespace rack::components {

inline constexpr FieldUnit kMonitorUnits[] = {{"latency_ns", "ns"}, {"latency_max_ns", "ns"}, {"real_period_ns", "ns"}};
inline constexpr DataTypeInfo kMonitorType = data_type_info<interfaces::MonitorData>("MonitorData", {}, kMonitorUnits);

}  // namespace rack::components
