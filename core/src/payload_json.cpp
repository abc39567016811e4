#include "rack/core/payload_json.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

namespace rack {

std::string json_escape(const std::string& text) {
  std::string out;
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  return out;
}

namespace {

template <typename T>
T load(const std::byte* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

std::string number(const tims::FieldDesc& f, const std::byte* p) {
  char buf[64];
  using tims::FieldKind;
  switch (f.kind) {
    case FieldKind::kI8: return std::to_string(load<int8_t>(p));
    case FieldKind::kU8: return std::to_string(load<uint8_t>(p));
    case FieldKind::kBool: return load<uint8_t>(p) != 0 ? "true" : "false";
    case FieldKind::kChar: return std::to_string(load<char>(p));
    case FieldKind::kI16: return std::to_string(load<int16_t>(p));
    case FieldKind::kU16: return std::to_string(load<uint16_t>(p));
    case FieldKind::kI32: return std::to_string(load<int32_t>(p));
    case FieldKind::kU32: return std::to_string(load<uint32_t>(p));
    case FieldKind::kI64: return std::to_string(load<int64_t>(p));
    case FieldKind::kU64: return std::to_string(load<uint64_t>(p));
    case FieldKind::kF32: {
      const float v = load<float>(p);
      if (!std::isfinite(v)) return "null";
      std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(v));
      return buf;
    }
    case FieldKind::kF64: {
      const double v = load<double>(p);
      if (!std::isfinite(v)) return "null";
      std::snprintf(buf, sizeof buf, "%.17g", v);
      return buf;
    }
  }
  return "null";
}

}  // namespace

std::string payload_to_json(std::span<const tims::FieldDesc> fields, std::span<const std::byte> body,
                            bool native) {
  std::vector<std::byte> copy(body.begin(), body.end());
  if (!native) tims::swap_fields(fields, copy.data(), copy.size());
  std::string out = "{";
  bool first = true;
  for (const auto& f : fields) {
    const uint32_t w = tims::field_kind_size(f.kind);
    if (f.offset + std::size_t{w} * f.count > copy.size()) continue;
    const std::byte* p = copy.data() + f.offset;
    if (!first) out += ", ";
    first = false;
    out += "\"" + json_escape(f.name) + "\": ";
    if (f.kind == tims::FieldKind::kChar && f.count > 1) {
      const auto* s = reinterpret_cast<const char*>(p);
      out += "\"" + json_escape(std::string(s, strnlen(s, f.count))) + "\"";
    } else if (f.count == 1) {
      out += number(f, p);
    } else {
      out += "[";
      for (uint32_t i = 0; i < f.count; ++i) {
        if (i > 0) out += ", ";
        out += number(f, p + std::size_t{i} * w);
      }
      out += "]";
    }
  }
  return out + "}";
}

}  // namespace rack
