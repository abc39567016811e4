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

// The name of one value of an enum-valued field (Pilot status 3 -> "BLOCKED").
struct ValueName {
  uint32_t value;
  const char* name;  // printable, at most 64 bytes: "BLOCKED", "RTK_FIXED", "2D"
};

// Names for the values of one field of a data type, which tools print beside the raw
// value (rackctl's "names" object): an enum (`values`), or a field that holds a raw
// TiMS address (`address`: printed as the component it names, "Pilot(0/0)"). The
// field is an unsigned or signed integer of at most 4 bytes, one element.
struct FieldValueNames {
  const char* field;                  // the field's name in the type's field table
  std::span<const ValueName> values;  // empty for an address field
  bool address = false;
};

// The unit of one field of a data type, which tools print beside its value and in the
// class's description ("m", "rad", "m/s", "ms"; printable, at most 64 bytes).
struct FieldUnit {
  const char* field;  // the field's name in the type's field table
  const char* unit;
};

struct DataTypeInfo {
  const char* type_name;                           // "ChassisData"
  uint32_t size;                                   // bytes of one sample (or body)
  std::span<const tims::FieldDesc> fields;         // by offset; see tims::fields_of<T>
  std::span<const FieldValueNames> value_names{};  // of a sample type's enum and address fields
  std::span<const FieldUnit> units{};              // of a sample type's fields that have one
};

// The info of a struct that declares `static constexpr auto fields()` (RACK_FIELD),
// with the value names of its enum and address fields and the units of its fields, if any.
template <typename T>
constexpr DataTypeInfo data_type_info(const char* name, std::span<const FieldValueNames> value_names = {},
                                      std::span<const FieldUnit> units = {}) noexcept {
  return DataTypeInfo{name, sizeof(T), std::span<const tims::FieldDesc>(tims::fields_of<T>), value_names, units};
}

// A class command as rackctl send names it.
struct CommandInfo {
  const char* name;          // RACK's name, upper case: "INIT", "SET_DESTINATION"
  int8_t type;               // the request type
  const DataTypeInfo* body;  // its body; nullptr: the command takes no body
  const char* summary;       // one line for rackctl's help
};

}  // namespace rack
