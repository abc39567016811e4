// A component class's description as tools receive it (issue 19, item 3): what a
// class declares (rack/core/class_types.h, rack::ComponentClass) and the parameters
// its components declare, so that rackctl, gdos and rack-gui print, parse and send
// the messages of a class they were not compiled with.
//
// The request: GET_CLASS (tims::msg::kGetClass) to any component's command mailbox,
// body ClassPageRequest (a byte offset into the encoded description). The reply:
// CLASS (kClass), body ClassPageHeader + at most kClassPageBytes bytes of the encoded
// description from that offset. A description is paged because a class with many
// documented parameters can exceed what a small mailbox slot holds; a client asks for
// offset 0, then for the next offset until it has `total` bytes, then decodes them.
// Every component of one class gives the same description (its parameters are
// declared by the class's constructor), so a client caches it per host and class id.
//
// The encoding (one place: encode_class_description / decode_class_description) is
// byte-order independent (little-endian integers, IEEE doubles as their bit pattern):
//
//   "RKCD" u8 version(1) u8 class_id u16 reserved
//   str impl, str class_name, str summary
//   u8 has_data [type]
//   u16 n_commands { str name, i8 type, str summary, u8 has_body [type] }
//   u16 n_params   { str name, u8 kind, u8 flags, str unit, f64 min, f64 max,
//                    str default, str doc, u8 n_choices { str choice } }
//   [value names: only when the request asks for them (ClassPageRequest.sections)
//    and the class declares some]
//   u16 n_named    { str field, u8 flags (1: address), u16 n_values { u32 value, str name } }
//   [field units: only when the request asks for them (kClassSectionFieldUnits) and
//    the data type declares some; the value-names section precedes them then, with
//    n_named = 0 when the class names no values]
//   u16 n_units    { u16 field (index into the data type's fields, increasing), str unit }
//   type = str name, u32 size, u16 n_fields { str name, u8 kind, u32 offset, u32 count }
//   str  = u16 length + bytes (no NUL)
//
// The value-names section (the names of the data type's enum values and address
// fields, rack/core/class_types.h FieldValueNames) follows the parameters. It is
// served only to a client that asks for it (ClassPageRequest.sections bit
// kClassSectionValueNames): a client that does not know it gets exactly the bytes it
// always got (the description without it, with that length as `total`), and a client
// that asks an executor that does not know it gets those too and decodes no names.
// The field-units section (the units of the data type's fields, rack::FieldUnit)
// follows it the same way (bit kClassSectionFieldUnits, which brings the value names
// with it): a client that asks only for names, or an executor that predates units,
// gives exactly the bytes it gave before units.
//
// The decoder is total: it is network input. Counts and lengths are bounded (kMax*),
// strings hold no control characters (they are printed on terminals), names are
// identifiers, kinds are known, every field lies inside its type, no bytes are left
// over; a refusal says what and at which byte offset.
//
// Depends on tims/ (FieldKind) and wire.h (ParamKind) only, so that a client library
// can take this file without the executor.
//
// Real-time contract: not RT-safe (allocates); tools and the executor's set-up. The
// command task serves bytes encoded before it started.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rack/core/wire.h"
#include "rack/tims/payload.h"

namespace rack {

inline constexpr std::size_t kClassPageBytes = 8192;  // bytes of description per CLASS reply
inline constexpr std::size_t kMaxClassDescriptionBytes = 256 * 1024;
inline constexpr std::size_t kMaxDescriptionName = 64;       // names: class, type, field, command, parameter, unit
inline constexpr std::size_t kMaxDescriptionText = 1024;     // summaries, docs, default values, choices
inline constexpr std::size_t kMaxDescriptionFields = 1024;   // per type
inline constexpr std::size_t kMaxDescriptionCommands = 107;  // types 21..127
inline constexpr std::size_t kMaxDescriptionParams = 512;
inline constexpr std::size_t kMaxDescriptionChoices = 64;
inline constexpr std::size_t kMaxDescriptionValueNames = 256;  // per field
inline constexpr uint8_t kClassDescriptionVersion = 1;

struct FieldDescription {
  std::string name;
  tims::FieldKind kind = tims::FieldKind::kU8;
  uint32_t offset = 0;
  uint32_t count = 1;
  std::string unit;  // "m/s"; empty: none. Data types only (the field-units section)
  bool operator==(const FieldDescription&) const = default;
};

struct TypeDescription {
  std::string name;   // "ChassisData"
  uint32_t size = 0;  // bytes
  std::vector<FieldDescription> fields;
  bool operator==(const TypeDescription&) const = default;
  // The field table as tims::FieldDesc (names point into this description: keep it
  // alive and unchanged while the table is used), for payload_to_json and
  // set_field_from_text.
  [[nodiscard]] std::vector<tims::FieldDesc> field_table() const;
};

struct CommandDescription {
  std::string name;  // "SET_DESTINATION"
  int8_t type = 0;   // 21..127
  std::string summary;
  std::optional<TypeDescription> body;  // none: the command takes no body
  bool operator==(const CommandDescription&) const = default;
};

struct ParameterDescription {
  static constexpr uint8_t kRequired = 0x01;
  static constexpr uint8_t kInitOnly = 0x02;
  static constexpr uint8_t kComponentRef = 0x04;
  std::string name;
  wire::ParamKind kind = wire::ParamKind::kInt;
  uint8_t flags = 0;  // kRequired | kInitOnly | kComponentRef
  std::string unit;   // "m/s"; empty: none
  double min = 0.0;   // -inf/+inf: unbounded
  double max = 0.0;
  std::string default_value;  // the declared value as text
  std::string doc;
  std::vector<std::string> choices;  // string parameters of a fixed set
  bool operator==(const ParameterDescription& o) const;
};

// The names of the values of one field of the data type (rack::FieldValueNames).
struct ValueNameDescription {
  uint32_t value = 0;
  std::string name;
  bool operator==(const ValueNameDescription&) const = default;
};
struct FieldNamesDescription {
  std::string field;     // a field of the class's data type
  bool address = false;  // holds a TiMS address: named as its component
  std::vector<ValueNameDescription> values;
  bool operator==(const FieldNamesDescription&) const = default;
  [[nodiscard]] const char* name_of(uint32_t value) const noexcept;  // nullptr: no name
};

struct ClassDescription {
  std::string impl;        // the host files' class: "ChassisSim"
  std::string class_name;  // the addresses' class: "Chassis" (Chassis(0/0))
  uint8_t class_id = 0;    // TiMS class id
  std::string summary;
  std::optional<TypeDescription> data;  // none: publishes no samples
  std::vector<CommandDescription> commands;
  std::vector<ParameterDescription> parameters;
  std::vector<FieldNamesDescription> value_names;  // of data's fields (empty: none or not asked)
  bool operator==(const ClassDescription&) const = default;

  [[nodiscard]] const CommandDescription* find_command(std::string_view name) const noexcept;
  [[nodiscard]] const ParameterDescription* find_parameter(std::string_view name) const noexcept;
};

// The bytes of a description. Throws std::invalid_argument when it breaks a limit the
// decoder enforces (a class that a client would refuse is refused at registration).
// `base_size`, when given, is set to the length of the description without its
// optional sections (what a client that does not ask for them is served).
[[nodiscard]] std::vector<std::byte> encode_class_description(const ClassDescription& d,
                                                              std::size_t* base_size = nullptr);

// Decodes `bytes` completely into `out`. On refusal returns false and sets `error` to
// what is wrong and where ("byte 57: parameter 3 'speed': unit has a control
// character"); `out` is then unspecified.
[[nodiscard]] bool decode_class_description(std::span<const std::byte> bytes, ClassDescription& out,
                                            std::string& error);

// GET_CLASS request body: where the requested page starts.
// `sections`: the optional sections the client reads (0 from clients that predate
// them, which are served the description without them).
inline constexpr uint32_t kClassSectionValueNames = 0x1;
inline constexpr uint32_t kClassSectionFieldUnits = 0x2;  // with the value names
struct ClassPageRequest {
  uint32_t offset = 0;
  uint32_t sections = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ClassPageRequest, offset), RACK_FIELD(ClassPageRequest, sections)};
  }
};

// CLASS reply body: this header, then min(kClassPageBytes, total - offset) bytes.
struct ClassPageHeader {
  uint32_t total = 0;   // bytes of the whole encoded description
  uint32_t offset = 0;  // where this page starts
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ClassPageHeader, total), RACK_FIELD(ClassPageHeader, offset)};
  }
};

// A client's assembly of the pages of one description. add() takes one CLASS reply
// body (byte order as its header flag says) and returns false with `error` when it is
// not the page asked for (next_offset()) or its figures are out of bounds. Not RT-safe.
class ClassPageAssembler {
 public:
  [[nodiscard]] bool add(std::span<const std::byte> body, bool native, std::string& error);
  [[nodiscard]] bool complete() const noexcept { return started_ && bytes_.size() == total_; }
  [[nodiscard]] uint32_t next_offset() const noexcept { return static_cast<uint32_t>(bytes_.size()); }
  [[nodiscard]] std::span<const std::byte> bytes() const noexcept { return bytes_; }

 private:
  std::vector<std::byte> bytes_;
  uint32_t total_ = 0;
  bool started_ = false;
};

// The page of `encoded` that a GET_CLASS request body asks for, written to `header`
// and `page` (a span into `encoded`); nullptr on success, otherwise the reason
// (malformed body, offset past the end). RT-safe (no allocation): the command task
// serves pages with it.
// The sections served: none, the value names (up to their end, which it finds by
// walking them), or all (units asked).
// `base_size`: the length of `encoded` without its optional sections (served when the
// request does not ask for them).
[[nodiscard]] const char* class_page(std::span<const std::byte> encoded, std::size_t base_size,
                                     std::span<const std::byte> request, bool native, ClassPageHeader& header,
                                     std::span<const std::byte>& page) noexcept;

[[nodiscard]] const char* describe(tims::FieldKind kind) noexcept;  // "f64"

}  // namespace rack
