// The sample type each component class publishes, by TiMS class id, so that tools
// (rackctl get-data, watch) can print any component's data as JSON, and the class
// commands each class takes with their bodies (rackctl send).
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

// A class command (request types 21..127) as rackctl send names it.
struct CommandInfo {
  const char* name;          // RACK's name, upper case: "INIT", "SET_DESTINATION"
  int8_t type;               // the request type
  const DataTypeInfo* body;  // its body; nullptr: the command takes no body
  const char* summary;       // one line for rackctl's help
};

// The class commands of a class; empty when it has none or is unknown here.
[[nodiscard]] std::span<const CommandInfo> commands_for_class(uint8_t class_id) noexcept;

}  // namespace rack::interfaces
