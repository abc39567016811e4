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
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "rack/core/class_description.h"
#include "rack/tims/address.h"
#include "rack/tims/payload.h"

namespace rack::tools {

// The text of a component address in an address field: "Pilot(0/0)", the class as
// the tool knows it (from that component's class description). The tool's own
// namer: a tool links no class, so TiMS names only the executor's and tools' classes.
using AddressNamer = std::function<std::string(tims::Address)>;

// {"field":"NAME",...} for a sample laid out by `fields`, with the value names its
// class declares (ClassDescription::value_names, from GET_CLASS); empty when none
// of those fields is in `sample`. Address fields are named by `name_of` (called with
// the component's command address; nullptr: TiMS' text, Class0xNN for a class it
// does not name).
[[nodiscard]] std::string field_names_json(std::span<const FieldNamesDescription> names,
                                           std::span<const tims::FieldDesc> fields, std::span<const std::byte> sample,
                                           bool native, const AddressNamer& name_of = nullptr);

// The field `name` of `fields`, nullptr when there is none.
[[nodiscard]] const tims::FieldDesc* find_field(std::span<const tims::FieldDesc> fields, std::string_view name);
// An unsigned scalar field of up to 8 bytes of `sample` (byte order as `native`
// says), read through its table entry; nullopt when it is not one or lies outside
// the sample. For tools that read a few fields of a sample by name (rack-gui's
// camera image, the chassis' active pilot).
[[nodiscard]] std::optional<uint64_t> unsigned_field(const tims::FieldDesc& field, std::span<const std::byte> sample,
                                                     bool native);

}  // namespace rack::tools
