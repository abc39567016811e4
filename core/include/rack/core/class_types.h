// What a component class declares about its messages: the sample type it publishes
// (with a field table, so tools can print it by name) and the class commands it
// takes (request types 21..127) with their bodies. The executor serves these to
// tools; a class built outside the tree declares them the same way.
//
// Real-time contract: plain constant data; reading it is RT-safe.
#pragma once

#include <cstdint>
#include <span>

#include "rack/tims/payload.h"

namespace rack {

struct DataTypeInfo {
  const char* type_name;                   // "ChassisData"
  uint32_t size;                           // bytes of one sample (or body)
  std::span<const tims::FieldDesc> fields;  // by offset; see tims::fields_of<T>
};

// The info of a struct that declares `static constexpr auto fields()` (RACK_FIELD).
template <typename T>
constexpr DataTypeInfo data_type_info(const char* name) noexcept {
  return DataTypeInfo{name, sizeof(T), std::span<const tims::FieldDesc>(tims::fields_of<T>)};
}

// A class command as rackctl send names it.
struct CommandInfo {
  const char* name;          // RACK's name, upper case: "INIT", "SET_DESTINATION"
  int8_t type;               // the request type
  const DataTypeInfo* body;  // its body; nullptr: the command takes no body
  const char* summary;       // one line for rackctl's help
};

}  // namespace rack
