// The sample type each component class publishes, by TiMS class id, so that tools
// (rackctl get-data, watch) can print any component's data as JSON, and the class
// commands each class takes with their bodies (rackctl send).
//
// Real-time contract: RT-safe look-up (a static table).
#pragma once

#include <cstdint>
#include <span>

#include "rack/core/class_types.h"

namespace rack::interfaces {

using rack::DataTypeInfo;
using rack::CommandInfo;

// nullptr when the class publishes no data or is unknown here.
[[nodiscard]] const DataTypeInfo* data_type_for_class(uint8_t class_id) noexcept;

// The class commands of a class; empty when it has none or is unknown here.
[[nodiscard]] std::span<const CommandInfo> commands_for_class(uint8_t class_id) noexcept;

}  // namespace rack::interfaces
