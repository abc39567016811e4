#include "field_names.h"

#include <array>
#include <cstring>
#include <utility>
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

// A scalar field's bits (up to 8 bytes) in host order; nullopt when it is an array
// or lies outside the sample.
std::optional<uint64_t> raw_bits(const tims::FieldDesc& f, std::span<const std::byte> sample, bool native) {
  const uint32_t size = tims::field_kind_size(f.kind);
  if (f.count != 1 || size > 8 || f.offset > sample.size() || sample.size() - f.offset < size) return std::nullopt;
  std::array<unsigned char, 8> b{};
  std::memcpy(b.data(), sample.data() + f.offset, size);
  if (!native && size > 1) {
    for (uint32_t i = 0; i < size / 2; ++i) std::swap(b[i], b[size - 1 - i]);
  }
  switch (size) {
    case 1: return b[0];
    case 2: {
      uint16_t v = 0;
      std::memcpy(&v, b.data(), 2);
      return v;
    }
    case 4: {
      uint32_t v = 0;
      std::memcpy(&v, b.data(), 4);
      return v;
    }
    default: {
      uint64_t v = 0;
      std::memcpy(&v, b.data(), 8);
      return v;
    }
  }
}

}  // namespace

const tims::FieldDesc* find_field(std::span<const tims::FieldDesc> fields, std::string_view name) {
  for (const auto& f : fields) {
    if (f.name != nullptr && name == f.name) return &f;
  }
  return nullptr;
}

std::optional<uint64_t> unsigned_field(const tims::FieldDesc& f, std::span<const std::byte> sample, bool native) {
  if (f.kind == tims::FieldKind::kF32 || f.kind == tims::FieldKind::kF64) return std::nullopt;
  return raw_bits(f, sample, native);
}

std::string field_names_json(std::span<const FieldNamesDescription> names, std::span<const tims::FieldDesc> fields,
                             std::span<const std::byte> sample, bool native, const AddressNamer& name_of) {
  std::string out;
  for (const auto& f : fields) {
    const FieldNamesDescription* n = names_of(names, f.name);
    if (n == nullptr) continue;
    const auto read = tims::field_kind_size(f.kind) <= 4 ? raw_bits(f, sample, native) : std::nullopt;
    if (!read) continue;
    const auto v = static_cast<uint32_t>(*read);
    std::string name;
    if (n->address) {
      const tims::Address a = tims::Address(v).component();  // the component, not its mailbox
      name = v == 0 ? "none" : name_of ? name_of(a) : a.str();
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
