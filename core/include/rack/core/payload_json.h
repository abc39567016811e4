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
[[nodiscard]] std::string payload_to_json(std::span<const tims::FieldDesc> fields,
                                          std::span<const std::byte> body, bool native);
[[nodiscard]] std::string json_escape(const std::string& text);

}  // namespace rack
