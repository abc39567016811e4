#include "rack/core/payload_json.h"

#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

namespace rack {

namespace {

// Length of the well-formed UTF-8 sequence at text[i] (RFC 3629: no overlong forms,
// no surrogates, nothing above U+10FFFF), or 0 when the bytes there are not one.
std::size_t utf8_sequence(const std::string& text, std::size_t i) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(text[i + k]); };
  const auto cont = [&](std::size_t k, unsigned char lo = 0x80, unsigned char hi = 0xBF) {
    return i + k < text.size() && b(k) >= lo && b(k) <= hi;
  };
  const unsigned char c = b(0);
  if (c >= 0xC2 && c <= 0xDF) return cont(1) ? 2 : 0;
  if (c == 0xE0) return cont(1, 0xA0) && cont(2) ? 3 : 0;
  if ((c >= 0xE1 && c <= 0xEC) || c == 0xEE || c == 0xEF) return cont(1) && cont(2) ? 3 : 0;
  if (c == 0xED) return cont(1, 0x80, 0x9F) && cont(2) ? 3 : 0;
  if (c == 0xF0) return cont(1, 0x90) && cont(2) && cont(3) ? 4 : 0;
  if (c >= 0xF1 && c <= 0xF3) return cont(1) && cont(2) && cont(3) ? 4 : 0;
  if (c == 0xF4) return cont(1, 0x80, 0x8F) && cont(2) && cont(3) ? 4 : 0;
  return 0;
}

}  // namespace

// JSON text is UTF-8 (RFC 8259 8.1): a byte that does not start a well-formed sequence
// (a payload's char array is whatever its sender wrote) becomes U+FFFD, as a UTF-8
// decoder shows it; otherwise rack-gui's parser refused the whole sample (found by
// fuzz_payload).
std::string json_escape(const std::string& text) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
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
        } else if (c < 0x80) {
          out += static_cast<char>(c);
        } else if (const std::size_t n = utf8_sequence(text, i); n > 0) {
          out.append(text, i, n);
          i += n - 1;
        } else {
          out += "\\ufffd";
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
      // The shortest text that reads back as the same float: 0.1f is "0.1", not
      // "0.100000001" (numbers for people; nothing of the value is lost).
      const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
      if (ec != std::errc()) std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(v));
      else *end = '\0';
      return buf;
    }
    case FieldKind::kF64: {
      const double v = load<double>(p);
      if (!std::isfinite(v)) return "null";
      // Shortest round-trip text: 0.3 is "0.3", not "0.29999999999999999".
      const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
      if (ec != std::errc()) std::snprintf(buf, sizeof buf, "%.17g", v);
      else *end = '\0';
      return buf;
    }
  }
  return "null";
}

}  // namespace

std::string payload_to_json(std::span<const tims::FieldDesc> fields, std::span<const std::byte> body, bool native) {
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
    out += '"';
    out += json_escape(f.name);
    out += "\": ";
    if (f.kind == tims::FieldKind::kChar && f.count > 1) {
      const auto* s = reinterpret_cast<const char*>(p);
      out += '"';
      out += json_escape(std::string(s, strnlen(s, f.count)));
      out += '"';
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

namespace {

template <typename T>
void store(std::byte* p, T v) {
  std::memcpy(p, &v, sizeof v);
}

template <typename T>
std::string store_integer(std::byte* p, const std::string& text) {
  // Integers of every width go through int64/uint64 so that the range check names
  // the field's own range.
  if constexpr (std::is_signed_v<T>) {
    int64_t v = 0;
    const char* first = text.data();
    // A '+' may stand where a '-' could; "+-5" is not a number (it read as -5).
    if (!text.empty() && text[0] == '+' && (text.size() == 1 || text[1] != '-')) ++first;
    const auto [ptr, ec] = std::from_chars(first, text.data() + text.size(), v);
    if (ec != std::errc() || ptr != text.data() + text.size() || first == text.data() + text.size()) {
      return "'" + text + "' is not an integer";
    }
    if (v < std::numeric_limits<T>::min() || v > std::numeric_limits<T>::max()) {
      return "'" + text + "' is outside " + std::to_string(std::numeric_limits<T>::min()) + ".." +
             std::to_string(std::numeric_limits<T>::max());
    }
    store(p, static_cast<T>(v));
  } else {
    // Unsigned fields take hex too (0x…): TiMS addresses are read that way.
    uint64_t v = 0;
    const bool hex = text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X');
    const char* first = text.data() + (hex ? 2 : (!text.empty() && text[0] == '+' ? 1 : 0));
    const char* last = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(first, last, v, hex ? 16 : 10);
    if (ec != std::errc() || ptr != last || first == last) return "'" + text + "' is not an unsigned integer";
    if (v > std::numeric_limits<T>::max()) {
      return "'" + text + "' is outside 0.." + std::to_string(std::numeric_limits<T>::max());
    }
    store(p, static_cast<T>(v));
  }
  return {};
}

std::string store_element(const tims::FieldDesc& f, std::byte* p, const std::string& text) {
  using K = tims::FieldKind;
  switch (f.kind) {
    case K::kBool:
      if (text == "true" || text == "1") store(p, uint8_t{1});
      else if (text == "false" || text == "0") store(p, uint8_t{0});
      else return "'" + text + "' is not a bool (true, false, 1 or 0)";
      return {};
    case K::kChar: return store_integer<int8_t>(p, text);
    case K::kI8: return store_integer<int8_t>(p, text);
    case K::kU8: return store_integer<uint8_t>(p, text);
    case K::kI16: return store_integer<int16_t>(p, text);
    case K::kU16: return store_integer<uint16_t>(p, text);
    case K::kI32: return store_integer<int32_t>(p, text);
    case K::kU32: return store_integer<uint32_t>(p, text);
    case K::kI64: return store_integer<int64_t>(p, text);
    case K::kU64: return store_integer<uint64_t>(p, text);
    case K::kF32:
    case K::kF64: {
      if (text.empty() || std::isspace(static_cast<unsigned char>(text[0])) != 0) {
        return "'" + text + "' is not a number";
      }
      errno = 0;
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) {
        return "'" + text + "' is not a finite number";
      }
      if (f.kind == K::kF32) {
        if (std::fabs(v) > std::numeric_limits<float>::max()) return "'" + text + "' does not fit a float";
        store(p, static_cast<float>(v));
      } else {
        store(p, v);
      }
      return {};
    }
  }
  return "unknown field kind";
}

}  // namespace

std::string set_field_from_text(const tims::FieldDesc& field, std::span<std::byte> payload, const std::string& text) {
  const uint32_t w = tims::field_kind_size(field.kind);
  if (field.offset + std::size_t{w} * field.count > payload.size()) return "the field lies beyond the payload";
  std::byte* base = payload.data() + field.offset;
  if (field.kind == tims::FieldKind::kChar && field.count > 1) {
    if (text.size() >= field.count) {
      return "a text of at most " + std::to_string(field.count - 1) + " characters is needed, got " +
             std::to_string(text.size());
    }
    if (text.find('\0') != std::string::npos) return "a text with a NUL character would be cut there";
    std::memset(base, 0, field.count);
    std::memcpy(base, text.data(), text.size());
    return {};
  }
  // Elements are parsed into a scratch copy first: a bad element leaves the payload as it was.
  std::vector<std::byte> scratch(base, base + std::size_t{w} * field.count);
  std::size_t start = 0;
  uint32_t index = 0;
  while (true) {
    const std::size_t comma = field.count > 1 ? text.find(',', start) : std::string::npos;
    const std::string element = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (index >= field.count) {
      return "at most " + std::to_string(field.count) + " elements fit, got more";
    }
    if (std::string why = store_element(field, scratch.data() + std::size_t{index} * w, element); !why.empty()) {
      return field.count > 1 ? "element " + std::to_string(index) + ": " + why : why;
    }
    ++index;
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  std::memcpy(base, scratch.data(), scratch.size());
  return {};
}

}  // namespace rack
