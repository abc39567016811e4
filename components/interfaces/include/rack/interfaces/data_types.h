// The sample type each component class publishes, by TiMS class id, so that tools
// (rackctl get-data, watch) can print any component's data as JSON.
//
// Real-time contract: RT-safe look-up (a static table).
#pragma once

#include <cstdint>
#include <span>

#include "rack/tims/payload.h"

namespace rack::interfaces {

struct DataTypeInfo {
  const char* type_name;
  uint32_t size;
  std::span<const tims::FieldDesc> fields;
};

// nullptr when the class publishes no data or is unknown here.
[[nodiscard]] const DataTypeInfo* data_type_for_class(uint8_t class_id) noexcept;

}  // namespace rack::interfaces
