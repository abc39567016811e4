#include "field_names.h"

#include <array>
#include <cstring>
#include <string_view>

#include "rack/core/payload_json.h"
#include "rack/tims/address.h"

namespace rack::tools {
namespace {

const FieldNamesDescription* names_of(std::span<const FieldNamesDescription> names, std::string_view field) {
  for (const auto& n : names) {
    if (n.field == field) return &n;
  }
  return nullptr;
}

// An unsigned scalar field of up to 4 bytes, in host order; false when out of the sample.
bool read_unsigned(const tims::FieldDesc& f, std::span<const std::byte> sample, bool native, uint32_t& out) {
  const uint32_t size = tims::field_kind_size(f.kind);
  if (f.count != 1 || size > 4 || f.offset > sample.size() || sample.size() - f.offset < size) return false;
  std::array<unsigned char, 4> b{};
  std::memcpy(b.data(), sample.data() + f.offset, size);
  if (!native && size > 1) {
    for (uint32_t i = 0; i < size / 2; ++i) std::swap(b[i], b[size - 1 - i]);
  }
  switch (size) {
    case 1: out = b[0]; return true;
    case 2: {
      uint16_t v = 0;
      std::memcpy(&v, b.data(), 2);
      out = v;
      return true;
    }
    default: {
      std::memcpy(&out, b.data(), 4);
      return true;
    }
  }
}

}  // namespace

std::string field_names_json(std::span<const FieldNamesDescription> names, std::span<const tims::FieldDesc> fields,
                             std::span<const std::byte> sample, bool native) {
  std::string out;
  for (const auto& f : fields) {
    const FieldNamesDescription* n = names_of(names, f.name);
    if (n == nullptr) continue;
    uint32_t v = 0;
    if (!read_unsigned(f, sample, native, v)) continue;
    std::string name;
    if (n->address) {
      name = v == 0 ? "none" : tims::Address(v).component().str();  // the component, not its mailbox
    } else if (const char* known = n->name_of(v)) {
      name = known;
    } else {
      name = "UNKNOWN(" + std::to_string(v) + ")";
    }
    out += (out.empty() ? "{\"" : ",\"") + rack::json_escape(f.name) + "\":\"" + rack::json_escape(name) + "\"";
  }
  return out.empty() ? out : out + "}";
}

}  // namespace rack::tools
