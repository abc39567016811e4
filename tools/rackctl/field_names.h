// Numbers for people in rackctl's JSON samples: the name of each enum-valued field
// (Pilot status 3 -> "BLOCKED") and of each field that holds a TiMS address
// (Chassis active_pilot 1638400 -> "Pilot(0/0)"), given beside the raw values, which
// stay as they are:
//   {..., "data":{"status":3,...}, "names":{"status":"BLOCKED","mode":"DESTINATION"}}
//
// The names come from the class's description (GET_CLASS: the value names its data
// type declares, rack/core/class_types.h FieldValueNames), so a plug-in class's enum
// fields are named too. Not RT code (allocates). Reads the sample through its field
// table; a field whose value has no name gets "UNKNOWN(N)" (a newer executor may have
// more values).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "rack/core/class_description.h"
#include "rack/tims/payload.h"

namespace rack::tools {

// {"field":"NAME",...} for a sample laid out by `fields`, with the value names its
// class declares (ClassDescription::value_names, from GET_CLASS); empty when none
// of those fields is in `sample`.
[[nodiscard]] std::string field_names_json(std::span<const FieldNamesDescription> names,
                                           std::span<const tims::FieldDesc> fields, std::span<const std::byte> sample,
                                           bool native);

}  // namespace rack::tools
