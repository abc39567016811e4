#include "rack/core/class_description.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "rack/tims/message.h"

namespace rack {

namespace {

constexpr std::array<std::byte, 4> kMagic = {std::byte{'R'}, std::byte{'K'}, std::byte{'C'}, std::byte{'D'}};

bool is_identifier(std::string_view s) noexcept {
  if (s.empty()) return false;
  for (const char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '.' || c == '[' || c == ']';
    if (!ok) return false;
  }
  return true;
}

// Text for a terminal: no control characters (C0, DEL); bytes >= 0x80 pass (UTF-8).
bool is_printable(std::string_view s) noexcept {
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7F) return false;
  }
  return true;
}

bool valid_field_kind(uint8_t k) noexcept { return k <= static_cast<uint8_t>(tims::FieldKind::kF64); }
bool valid_param_kind(uint8_t k) noexcept { return k <= static_cast<uint8_t>(wire::ParamKind::kString); }

// Why entry `i` of `names` cannot name values of `data`'s fields ("" when it can):
// the field exists once, is an integer of at most 4 bytes and one element; an
// address field has no value names, an enum field at least one, each value and
// name once, names not empty.
std::string value_names_problem(const TypeDescription& data, const std::vector<FieldNamesDescription>& names,
                                std::size_t i) {
  const FieldNamesDescription& n = names[i];
  const std::string what = "value names of field '" + n.field + "'";
  for (std::size_t j = 0; j < i; ++j) {
    if (names[j].field == n.field) return what + ": the field is named twice";
  }
  const FieldDescription* f = nullptr;
  for (const auto& c : data.fields) {
    if (c.name == n.field) f = &c;
  }
  if (f == nullptr) return what + ": '" + data.name + "' has no such field";
  const bool integer = f->kind != tims::FieldKind::kF32 && f->kind != tims::FieldKind::kF64 &&
                       f->kind != tims::FieldKind::kChar && tims::field_kind_size(f->kind) <= 4;
  if (!integer || f->count != 1) return what + ": not an integer of at most 4 bytes (" + describe(f->kind) + ")";
  if (n.address && (!n.values.empty() || tims::field_kind_size(f->kind) != 4)) {
    return what + ": an address field is a u32 or i32 without value names";
  }
  if (!n.address && n.values.empty()) return what + ": no values";
  for (std::size_t a = 0; a < n.values.size(); ++a) {
    if (n.values[a].name.empty()) return what + ": value " + std::to_string(n.values[a].value) + " has an empty name";
    for (std::size_t b = 0; b < a; ++b) {
      if (n.values[b].value == n.values[a].value)
        return what + ": value " + std::to_string(n.values[a].value) + " named twice";
      if (n.values[b].name == n.values[a].name) return what + ": name '" + n.values[a].name + "' given twice";
    }
  }
  return "";
}

// Where the value-names section that starts at `at` ends in `encoded` (this file's own
// encoding): `at` when it names no field (written only before the units, and never
// served without them). RT-safe: a bounded walk, no allocation; bytes that do not
// walk (not this encoder's) end it at the end of `encoded`.
std::size_t value_names_end(std::span<const std::byte> encoded, std::size_t at) noexcept {
  std::size_t i = at;
  bool ok = true;
  const auto u16 = [&]() -> std::size_t {
    if (!ok || encoded.size() - i < 2) {
      ok = false;
      return 0;
    }
    const std::size_t v = std::to_integer<std::size_t>(encoded[i]) |
                          (std::to_integer<std::size_t>(encoded[i + 1]) << 8);
    i += 2;
    return v;
  };
  const auto skip = [&](std::size_t n) {
    if (!ok || encoded.size() - i < n) {
      ok = false;
      return;
    }
    i += n;
  };
  if (at > encoded.size()) return encoded.size();
  const std::size_t named = u16();
  if (!ok || named == 0) return at;
  for (std::size_t f = 0; f < named && ok; ++f) {
    skip(u16());  // the field's name
    skip(1);      // flags
    const std::size_t values = u16();
    for (std::size_t v = 0; v < values && ok; ++v) {
      skip(4);      // the value
      skip(u16());  // its name
    }
  }
  return ok ? i : encoded.size();
}

// ---------------------------------------------------------------- encoder

class Writer {
 public:
  void u8(uint8_t v) { out_.push_back(std::byte{v}); }
  void u16(uint16_t v) {
    u8(static_cast<uint8_t>(v));
    u8(static_cast<uint8_t>(v >> 8));
  }
  void u32(uint32_t v) {
    for (int i = 0; i < 4; ++i) u8(static_cast<uint8_t>(v >> (8 * i)));
  }
  void u64(uint64_t v) {
    for (int i = 0; i < 8; ++i) u8(static_cast<uint8_t>(v >> (8 * i)));
  }
  void f64(double v) { u64(std::bit_cast<uint64_t>(v)); }
  void str(const std::string& s, std::size_t max, bool identifier, const char* what) {
    if (s.size() > max)
      throw std::invalid_argument(std::string(what) + " '" + s + "' is longer than " + std::to_string(max));
    if (identifier ? !is_identifier(s) : !is_printable(s)) {
      throw std::invalid_argument(std::string(what) + " '" + s + "' is not " +
                                  (identifier ? "a name (letters, digits, _ . [ ])" : "printable text"));
    }
    u16(static_cast<uint16_t>(s.size()));
    for (const char c : s) u8(static_cast<uint8_t>(c));
  }
  void count(std::size_t n, std::size_t max, const char* what) {
    if (n > max) throw std::invalid_argument(std::string("more than ") + std::to_string(max) + " " + what);
    u16(static_cast<uint16_t>(n));
  }
  void type(const TypeDescription& t) {
    str(t.name, kMaxDescriptionName, true, "type name");
    u32(t.size);
    count(t.fields.size(), kMaxDescriptionFields, "fields");
    for (const auto& f : t.fields) {
      str(f.name, kMaxDescriptionName, true, "field name");
      const uint64_t end = uint64_t{f.offset} + uint64_t{f.count} * tims::field_kind_size(f.kind);
      if (f.count == 0 || end > t.size) {
        throw std::invalid_argument("field '" + f.name + "' of '" + t.name + "' does not lie inside its " +
                                    std::to_string(t.size) + " bytes");
      }
      u8(static_cast<uint8_t>(f.kind));
      u32(f.offset);
      u32(f.count);
    }
  }
  std::vector<std::byte>& bytes() { return out_; }

 private:
  std::vector<std::byte> out_;
};

// ---------------------------------------------------------------- decoder

class Reader {
 public:
  explicit Reader(std::span<const std::byte> in) : in_(in) {}

  [[nodiscard]] bool failed() const noexcept { return !error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  [[nodiscard]] std::size_t left() const noexcept { return in_.size() - at_; }
  [[nodiscard]] std::size_t at() const noexcept { return at_; }
  void set_context(std::string c) { context_ = std::move(c); }
  void fail(const std::string& what) {
    if (failed()) return;
    error_ = "byte " + std::to_string(at_) + ": " + (context_.empty() ? "" : context_ + ": ") + what;
  }

  bool take(std::size_t n, const char* what) {
    if (failed()) return false;
    if (left() < n) {
      fail(std::string("ends inside ") + what + " (" + std::to_string(left()) + " bytes left, " + std::to_string(n) +
           " needed)");
      return false;
    }
    return true;
  }
  uint8_t u8(const char* what) {
    if (!take(1, what)) return 0;
    return std::to_integer<uint8_t>(in_[at_++]);
  }
  uint16_t u16(const char* what) {
    if (!take(2, what)) return 0;
    const auto v = static_cast<uint16_t>(std::to_integer<unsigned>(in_[at_]) |
                                         (std::to_integer<unsigned>(in_[at_ + 1]) << 8));
    at_ += 2;
    return v;
  }
  uint32_t u32(const char* what) {
    if (!take(4, what)) return 0;
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= std::to_integer<uint32_t>(in_[at_ + static_cast<std::size_t>(i)]) << (8 * i);
    at_ += 4;
    return v;
  }
  double f64(const char* what) {
    if (!take(8, what)) return 0.0;
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= std::to_integer<uint64_t>(in_[at_ + static_cast<std::size_t>(i)]) << (8 * i);
    at_ += 8;
    return std::bit_cast<double>(v);
  }
  std::string str(std::size_t max, bool identifier, const char* what) {
    const std::size_t start = at_;
    const uint16_t n = u16(what);
    if (failed()) return {};
    if (n > max) {
      at_ = start;
      fail(std::string(what) + " is " + std::to_string(n) + " bytes, at most " + std::to_string(max));
      return {};
    }
    if (!take(n, what)) return {};
    std::string s(reinterpret_cast<const char*>(in_.data() + at_), n);
    if (identifier ? !is_identifier(s) : !is_printable(s)) {
      fail(std::string(what) +
           (identifier ? " is not a name (letters, digits, _ . [ ], not empty)" : " has a control character"));
      return {};
    }
    at_ += n;
    return s;
  }
  std::size_t count(std::size_t max, const char* what) {
    const uint16_t n = u16(what);
    if (failed()) return 0;
    if (n > max) {
      at_ -= 2;
      fail(std::to_string(n) + " " + what + ", at most " + std::to_string(max));
      return 0;
    }
    return n;
  }
  bool type(TypeDescription& t) {
    t.name = str(kMaxDescriptionName, true, "type name");
    t.size = u32("type size");
    if (failed()) return false;
    if (t.size > kMaxTypeBytes) {
      fail("type '" + t.name + "' claims " + std::to_string(t.size) + " bytes, at most " +
           std::to_string(kMaxTypeBytes));
      return false;
    }
    const std::size_t n = count(kMaxDescriptionFields, "fields");
    t.fields.clear();
    for (std::size_t i = 0; i < n && !failed(); ++i) {
      FieldDescription f;
      f.name = str(kMaxDescriptionName, true, "field name");
      const uint8_t kind = u8("field kind");
      f.offset = u32("field offset");
      f.count = u32("field count");
      if (failed()) return false;
      if (!valid_field_kind(kind)) {
        fail("field '" + f.name + "' of '" + t.name + "' has unknown kind " + std::to_string(kind));
        return false;
      }
      f.kind = static_cast<tims::FieldKind>(kind);
      const uint64_t end = uint64_t{f.offset} + uint64_t{f.count} * tims::field_kind_size(f.kind);
      if (f.count == 0 || end > t.size) {
        fail("field '" + f.name + "' of '" + t.name + "' (offset " + std::to_string(f.offset) + ", " +
             std::to_string(f.count) + " x " + describe(f.kind) + ") does not lie inside its " +
             std::to_string(t.size) + " bytes");
        return false;
      }
      t.fields.push_back(std::move(f));
    }
    return !failed();
  }

  // The largest sample a description may declare (TiMS' largest message).
  static constexpr uint32_t kMaxTypeBytes = 64u << 20;

 private:
  std::span<const std::byte> in_;
  std::size_t at_ = 0;
  std::string error_;
  std::string context_;
};

}  // namespace

const char* describe(tims::FieldKind kind) noexcept {
  switch (kind) {
    case tims::FieldKind::kI8: return "i8";
    case tims::FieldKind::kU8: return "u8";
    case tims::FieldKind::kBool: return "bool";
    case tims::FieldKind::kChar: return "char";
    case tims::FieldKind::kI16: return "i16";
    case tims::FieldKind::kU16: return "u16";
    case tims::FieldKind::kI32: return "i32";
    case tims::FieldKind::kU32: return "u32";
    case tims::FieldKind::kI64: return "i64";
    case tims::FieldKind::kU64: return "u64";
    case tims::FieldKind::kF32: return "f32";
    case tims::FieldKind::kF64: return "f64";
  }
  return "?";
}

std::vector<tims::FieldDesc> TypeDescription::field_table() const {
  std::vector<tims::FieldDesc> out;
  out.reserve(fields.size());
  for (const auto& f : fields) out.push_back(tims::FieldDesc{f.name.c_str(), f.kind, f.offset, f.count});
  return out;
}

bool ParameterDescription::operator==(const ParameterDescription& o) const {
  // Bit patterns, so that infinities and NaN compare as the bytes that travel.
  return name == o.name && kind == o.kind && flags == o.flags && unit == o.unit &&
         std::bit_cast<uint64_t>(min) == std::bit_cast<uint64_t>(o.min) &&
         std::bit_cast<uint64_t>(max) == std::bit_cast<uint64_t>(o.max) && default_value == o.default_value &&
         doc == o.doc && choices == o.choices;
}

const char* FieldNamesDescription::name_of(uint32_t value) const noexcept {
  for (const auto& v : values) {
    if (v.value == value) return v.name.c_str();
  }
  return nullptr;
}

const CommandDescription* ClassDescription::find_command(std::string_view name) const noexcept {
  for (const auto& c : commands) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

const ParameterDescription* ClassDescription::find_parameter(std::string_view name) const noexcept {
  for (const auto& p : parameters) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

std::vector<std::byte> encode_class_description(const ClassDescription& d, std::size_t* base_size) {
  Writer w;
  for (const std::byte b : kMagic) w.u8(std::to_integer<uint8_t>(b));
  w.u8(kClassDescriptionVersion);
  w.u8(d.class_id);
  w.u16(0);
  w.str(d.impl, kMaxDescriptionName, true, "class");
  w.str(d.class_name, kMaxDescriptionName, true, "class name");
  w.str(d.summary, kMaxDescriptionText, false, "summary");
  w.u8(d.data ? 1 : 0);
  if (d.data) w.type(*d.data);
  w.count(d.commands.size(), kMaxDescriptionCommands, "commands");
  for (const auto& c : d.commands) {
    w.str(c.name, kMaxDescriptionName, true, "command name");
    if (c.type < tims::msg::kFirstClassCommand) {
      throw std::invalid_argument("command '" + c.name + "' has type " + std::to_string(c.type) + ", not 21..127");
    }
    w.u8(static_cast<uint8_t>(c.type));
    w.str(c.summary, kMaxDescriptionText, false, "command summary");
    w.u8(c.body ? 1 : 0);
    if (c.body) w.type(*c.body);
  }
  w.count(d.parameters.size(), kMaxDescriptionParams, "parameters");
  for (const auto& p : d.parameters) {
    w.str(p.name, kMaxDescriptionName, true, "parameter name");
    w.u8(static_cast<uint8_t>(p.kind));
    w.u8(p.flags);
    w.str(p.unit, kMaxDescriptionName, false, "unit");
    w.f64(p.min);
    w.f64(p.max);
    w.str(p.default_value, kMaxDescriptionText, false, "default value");
    w.str(p.doc, kMaxDescriptionText, false, "parameter doc");
    if (p.choices.size() > kMaxDescriptionChoices)
      throw std::invalid_argument("parameter '" + p.name + "': too many choices");
    w.u8(static_cast<uint8_t>(p.choices.size()));
    for (const auto& c : p.choices) w.str(c, kMaxDescriptionText, false, "choice");
  }
  if (base_size != nullptr) *base_size = w.bytes().size();
  std::size_t n_units = 0;
  for (const auto& c : d.commands) {
    if (!c.body) continue;
    for (const auto& f : c.body->fields) {
      if (!f.unit.empty())
        throw std::invalid_argument("command '" + c.name + "': field '" + f.name + "' has a unit (data types only)");
    }
  }
  if (d.data) {
    for (const auto& f : d.data->fields) {
      if (!f.unit.empty()) ++n_units;
    }
  }
  if (!d.value_names.empty() || n_units > 0) {
    if (!d.data) throw std::invalid_argument("class '" + d.impl + "': value names without a data type");
    // Empty only before the units (the decoder refuses an empty section at the end).
    w.count(d.value_names.size(), kMaxDescriptionFields, "fields with value names");
    for (std::size_t i = 0; i < d.value_names.size(); ++i) {
      const FieldNamesDescription& n = d.value_names[i];
      const std::string why = value_names_problem(*d.data, d.value_names, i);
      if (!why.empty()) throw std::invalid_argument("class '" + d.impl + "': " + why);
      w.str(n.field, kMaxDescriptionName, true, "named field");
      w.u8(n.address ? 1 : 0);
      w.count(n.values.size(), kMaxDescriptionValueNames, "value names");
      for (const auto& v : n.values) {
        w.u32(v.value);
        w.str(v.name, kMaxDescriptionName, false, "value name");
      }
    }
  }
  if (n_units > 0) {
    w.count(n_units, kMaxDescriptionFields, "fields with units");
    for (std::size_t i = 0; i < d.data->fields.size(); ++i) {
      const FieldDescription& f = d.data->fields[i];
      if (f.unit.empty()) continue;
      w.u16(static_cast<uint16_t>(i));
      w.str(f.unit, kMaxDescriptionName, false, "unit");
    }
  }
  if (w.bytes().size() > kMaxClassDescriptionBytes) {
    throw std::invalid_argument("class '" + d.impl + "': description of " + std::to_string(w.bytes().size()) +
                                " bytes, at most " + std::to_string(kMaxClassDescriptionBytes));
  }
  return std::move(w.bytes());
}

bool decode_class_description(std::span<const std::byte> bytes, ClassDescription& out, std::string& error) {
  Reader r(bytes);
  out = ClassDescription{};
  if (bytes.size() > kMaxClassDescriptionBytes) {
    error = "description of " + std::to_string(bytes.size()) + " bytes, at most " +
            std::to_string(kMaxClassDescriptionBytes);
    return false;
  }
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) != 0) {
    error = "byte 0: not a class description (no 'RKCD' mark)";
    return false;
  }
  for (int i = 0; i < 4; ++i) (void)r.u8("mark");
  const uint8_t version = r.u8("version");
  if (version != kClassDescriptionVersion) {
    r.fail("version " + std::to_string(version) + ", this tool reads version " +
           std::to_string(kClassDescriptionVersion));
  }
  out.class_id = r.u8("class id");
  if (r.u16("reserved") != 0) r.fail("reserved bytes are not 0");
  out.impl = r.str(kMaxDescriptionName, true, "class");
  out.class_name = r.str(kMaxDescriptionName, true, "class name");
  out.summary = r.str(kMaxDescriptionText, false, "summary");
  const uint8_t has_data = r.u8("data flag");
  if (!r.failed() && has_data > 1) r.fail("data flag is " + std::to_string(has_data) + ", not 0 or 1");
  if (!r.failed() && has_data == 1) {
    r.set_context("data type");
    out.data.emplace();
    (void)r.type(*out.data);
  }
  const std::size_t n_commands = r.count(kMaxDescriptionCommands, "commands");
  for (std::size_t i = 0; i < n_commands && !r.failed(); ++i) {
    r.set_context("command " + std::to_string(i));
    CommandDescription c;
    c.name = r.str(kMaxDescriptionName, true, "command name");
    r.set_context("command " + std::to_string(i) + " '" + c.name + "'");
    const uint8_t type = r.u8("command type");
    if (!r.failed() && (type < static_cast<uint8_t>(tims::msg::kFirstClassCommand) || type > 127)) {
      r.fail("type " + std::to_string(type) + " is not a class command (21..127)");
    }
    c.type = static_cast<int8_t>(type & 0x7F);
    c.summary = r.str(kMaxDescriptionText, false, "command summary");
    const uint8_t has_body = r.u8("body flag");
    if (!r.failed() && has_body > 1) r.fail("body flag is " + std::to_string(has_body) + ", not 0 or 1");
    if (!r.failed() && has_body == 1) {
      c.body.emplace();
      (void)r.type(*c.body);
    }
    if (!r.failed() && out.find_command(c.name) != nullptr) r.fail("command named twice");
    for (const auto& o : out.commands) {
      if (!r.failed() && o.type == c.type) r.fail("type " + std::to_string(type) + " also names '" + o.name + "'");
    }
    out.commands.push_back(std::move(c));
  }
  r.set_context("");
  const std::size_t n_params = r.count(kMaxDescriptionParams, "parameters");
  for (std::size_t i = 0; i < n_params && !r.failed(); ++i) {
    r.set_context("parameter " + std::to_string(i));
    ParameterDescription p;
    p.name = r.str(std::min<std::size_t>(kMaxDescriptionName, wire::kParamNameLen - 1), true, "parameter name");
    r.set_context("parameter " + std::to_string(i) + " '" + p.name + "'");
    const uint8_t kind = r.u8("parameter kind");
    if (!r.failed() && !valid_param_kind(kind)) r.fail("unknown kind " + std::to_string(kind));
    p.kind = static_cast<wire::ParamKind>(kind);
    p.flags = r.u8("parameter flags");
    if (!r.failed() && (p.flags & ~0x07u) != 0) r.fail("unknown flag bits");
    p.unit = r.str(kMaxDescriptionName, false, "unit");
    p.min = r.f64("min");
    p.max = r.f64("max");
    if (!r.failed() && (std::isnan(p.min) || std::isnan(p.max) || p.min > p.max)) r.fail("min and max are not a range");
    p.default_value = r.str(kMaxDescriptionText, false, "default value");
    p.doc = r.str(kMaxDescriptionText, false, "parameter doc");
    const uint8_t n_choices = r.u8("choice count");
    if (!r.failed() && n_choices > kMaxDescriptionChoices) {
      r.fail(std::to_string(n_choices) + " choices, at most " + std::to_string(kMaxDescriptionChoices));
    }
    for (std::size_t j = 0; j < n_choices && !r.failed(); ++j)
      p.choices.push_back(r.str(kMaxDescriptionText, false, "choice"));
    if (!r.failed() && out.find_parameter(p.name) != nullptr) r.fail("parameter named twice");
    out.parameters.push_back(std::move(p));
  }
  r.set_context("");
  // The value-names section, when the executor served it (asked for and declared).
  if (!r.failed() && r.left() != 0) {
    r.set_context("value names");
    if (!out.data) r.fail("value names in a class without a data type");
    const std::size_t n_named = r.count(kMaxDescriptionFields, "fields with value names");
    // Empty only when the units follow (otherwise the section is left out).
    if (!r.failed() && n_named == 0 && r.left() == 0) r.fail("the section names no field (it is left out then)");
    for (std::size_t i = 0; i < n_named && !r.failed(); ++i) {
      r.set_context("value names " + std::to_string(i));
      FieldNamesDescription n;
      n.field = r.str(kMaxDescriptionName, true, "named field");
      r.set_context("value names " + std::to_string(i) + " '" + n.field + "'");
      const uint8_t flags = r.u8("value-names flags");
      if (!r.failed() && flags > 1) r.fail("flags are " + std::to_string(flags) + ", not 0 or 1");
      n.address = flags == 1;
      const std::size_t n_values = r.count(kMaxDescriptionValueNames, "value names");
      for (std::size_t j = 0; j < n_values && !r.failed(); ++j) {
        ValueNameDescription v;
        v.value = r.u32("value");
        v.name = r.str(kMaxDescriptionName, false, "value name");
        n.values.push_back(std::move(v));
      }
      if (r.failed()) break;
      out.value_names.push_back(std::move(n));
      const std::string why = value_names_problem(*out.data, out.value_names, out.value_names.size() - 1);
      if (!why.empty()) r.fail(why);
    }
    r.set_context("");
  }
  // The field-units section, when the executor served it (asked for and declared).
  if (!r.failed() && r.left() != 0) {
    r.set_context("field units");
    if (!out.data) r.fail("field units in a class without a data type");
    const std::size_t n_units = r.count(kMaxDescriptionFields, "fields with units");
    if (!r.failed() && n_units == 0) r.fail("the section gives no unit (it is left out then)");
    std::size_t next = 0;  // fields in table order, each once: one encoding
    for (std::size_t i = 0; i < n_units && !r.failed(); ++i) {
      r.set_context("field units " + std::to_string(i));
      const uint16_t field = r.u16("field index");
      const std::string unit = r.str(kMaxDescriptionName, false, "unit");
      if (r.failed()) break;
      if (field < next || field >= out.data->fields.size()) {
        r.fail("field index " + std::to_string(field) + " is not a field of '" + out.data->name + "' after the " +
               (next == 0 ? std::string("start") : "previous one (" + std::to_string(next - 1) + ")") + " (" +
               std::to_string(out.data->fields.size()) + " fields)");
        break;
      }
      if (unit.empty()) {
        r.fail("field '" + out.data->fields[field].name + "' has an empty unit");
        break;
      }
      out.data->fields[field].unit = unit;
      next = std::size_t{field} + 1;
    }
    r.set_context("");
  }
  if (!r.failed() && r.left() != 0) r.fail(std::to_string(r.left()) + " bytes after the end of the description");
  if (r.failed()) {
    error = r.error();
    return false;
  }
  return true;
}

bool ClassPageAssembler::add(std::span<const std::byte> body, bool native, std::string& error) {
  ClassPageHeader h;
  if (body.size() < sizeof h) {
    error = "CLASS reply of " + std::to_string(body.size()) + " bytes, shorter than its 8-byte header";
    return false;
  }
  if (!wire::read_payload(body.first(sizeof h), native, h)) return false;
  const auto page = body.subspan(sizeof h);
  if (h.total == 0 || h.total > kMaxClassDescriptionBytes) {
    error = "CLASS reply claims a description of " + std::to_string(h.total) + " bytes (1.." +
            std::to_string(kMaxClassDescriptionBytes) + ")";
    return false;
  }
  if (started_ && h.total != total_) {
    error = "CLASS reply: the description changed size between pages (" + std::to_string(total_) + ", then " +
            std::to_string(h.total) + " bytes)";
    return false;
  }
  if (h.offset != next_offset()) {
    error = "CLASS reply at offset " + std::to_string(h.offset) + ", " + std::to_string(next_offset()) + " asked";
    return false;
  }
  const std::size_t expected = std::min<std::size_t>(kClassPageBytes, h.total - h.offset);
  if (page.size() != expected || expected == 0) {
    error = "CLASS reply page of " + std::to_string(page.size()) + " bytes, " + std::to_string(expected) + " expected";
    return false;
  }
  started_ = true;
  total_ = h.total;
  bytes_.insert(bytes_.end(), page.begin(), page.end());
  return true;
}

const char* class_page(std::span<const std::byte> encoded, std::size_t base_size, std::span<const std::byte> request,
                       bool native, ClassPageHeader& header, std::span<const std::byte>& page) noexcept {
  ClassPageRequest q;
  if (request.empty()) {
    q.offset = 0;
  } else if (!wire::read_payload(request, native, q)) {
    return "GET_CLASS: body must be empty or an 8-byte page request";
  }
  if (encoded.empty()) return "GET_CLASS: this component has no class description";
  // Without the optional sections for a client that does not ask for them.
  const std::size_t base = std::min(base_size, encoded.size());
  std::size_t total = base;
  if ((q.sections & kClassSectionFieldUnits) != 0) {
    total = encoded.size();
  } else if ((q.sections & kClassSectionValueNames) != 0) {
    total = value_names_end(encoded, base);
  }
  if (q.offset >= total) return "GET_CLASS: offset past the end of the description";
  header.total = static_cast<uint32_t>(total);
  header.offset = q.offset;
  page = encoded.subspan(q.offset, std::min<std::size_t>(kClassPageBytes, total - q.offset));
  return nullptr;
}

}  // namespace rack
