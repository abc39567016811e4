// Monitor's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (rack/interfaces/demo.h's MonitorData).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

inline constexpr FieldUnit kMonitorUnits[] = {{"latency_ns", "ns"}, {"latency_max_ns", "ns"}, {"real_period_ns", "ns"}};
inline constexpr DataTypeInfo kMonitorType = data_type_info<interfaces::MonitorData>("MonitorData", {}, kMonitorUnits);

}  // namespace rack::components
