// Numbers for people in rackctl's JSON samples: the name of each enum-valued field
// (Pilot status 3 -> "BLOCKED") and of each field that holds a TiMS address
// (Chassis active_pilot 1638400 -> "Pilot(0/0)"), given beside the raw values, which
// stay as they are:
//   {..., "data":{"status":3,...}, "names":{"status":"BLOCKED","mode":"DESTINATION"}}
//
// Not RT code (allocates). Reads the sample through its field table; a field whose
// value has no name gets "UNKNOWN(N)" (a newer executor may have more values).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "rack/tims/payload.h"

namespace rack::tools {

// {"field":"NAME",...} for the sample of a component of class `class_id` laid out by
// `fields`; empty when the class has no named fields (or none of them is in `sample`).
[[nodiscard]] std::string field_names_json(uint8_t class_id, std::span<const tims::FieldDesc> fields,
                                           std::span<const std::byte> sample, bool native);

// The name of value `v` of field `field` of class `class_id`; nullptr when that field
// is not an enum rackctl knows (addresses are not covered: see field_names_json).
[[nodiscard]] const char* enum_value_name(uint8_t class_id, const std::string& field, uint32_t v);

}  // namespace rack::tools
