// JSON text of a payload through its field table (rackctl get-data/watch, rackd).
//
// Real-time contract: not RT-safe (allocates). For tools and non-RT threads.
#pragma once

#include <cstddef>
#include <span>
#include <string>

#include "rack/tims/payload.h"

namespace rack {

// {"field": value, ...}; arrays as JSON arrays, char arrays as strings. Converts
// byte order first when `native` is false. Fields beyond `body` are left out.
[[nodiscard]] std::string payload_to_json(std::span<const tims::FieldDesc> fields, std::span<const std::byte> body,
                                          bool native);
[[nodiscard]] std::string json_escape(const std::string& text);

// Sets one field of a payload in host byte order from its text: integers and bools
// (true, false, 1, 0) as such, floats as finite numbers, arrays as comma-separated
// elements (at most the field's count; the rest keep their value), char arrays as a
// string shorter than the array. Range-checked for the field's kind. Returns the
// reason when the text does not fit the field (the payload is then unchanged), an
// empty string on success. `payload` must be at least the field's end.
[[nodiscard]] std::string set_field_from_text(const tims::FieldDesc& field, std::span<std::byte> payload,
                                              const std::string& text);

}  // namespace rack
