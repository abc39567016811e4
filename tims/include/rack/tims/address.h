// TiMS addresses: 32 bits = system (8) | class (8) | instance (8) | local mailbox (8).
// Local mailbox 0 is a component's command mailbox. Printed with its class's name
// (register_class_name) as `Name(0/1)`, or `Name(0/1)#3` for local mailbox 3.
//
// Real-time contract: Address and format() are RT-safe; parse() and the class table
// look-ups by name are RT-safe too (no allocation), but are meant for tools.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace rack::tims {

class Address {
 public:
  constexpr Address() noexcept = default;
  constexpr explicit Address(uint32_t raw) noexcept : raw_(raw) {}
  static constexpr Address make(uint8_t system, uint8_t class_id, uint8_t instance, uint8_t mailbox = 0) noexcept {
    return Address((uint32_t{system} << 24) | (uint32_t{class_id} << 16) | (uint32_t{instance} << 8) | mailbox);
  }

  [[nodiscard]] constexpr uint32_t raw() const noexcept { return raw_; }
  [[nodiscard]] constexpr uint8_t system() const noexcept { return static_cast<uint8_t>(raw_ >> 24); }
  [[nodiscard]] constexpr uint8_t class_id() const noexcept { return static_cast<uint8_t>(raw_ >> 16); }
  [[nodiscard]] constexpr uint8_t instance() const noexcept { return static_cast<uint8_t>(raw_ >> 8); }
  [[nodiscard]] constexpr uint8_t mailbox() const noexcept { return static_cast<uint8_t>(raw_); }
  // The component's command mailbox (local mailbox 0) of this address.
  [[nodiscard]] constexpr Address component() const noexcept { return Address(raw_ & 0xFFFFFF00u); }
  [[nodiscard]] constexpr Address with_mailbox(uint8_t mbx) const noexcept {
    return Address((raw_ & 0xFFFFFF00u) | mbx);
  }
  constexpr bool operator==(const Address&) const noexcept = default;

  // Writes the printable name (NUL-terminated, cut to `size`). RT-safe.
  void format(char* out, std::size_t size) const noexcept;
  [[nodiscard]] std::string str() const;  // not RT-safe (allocates)

 private:
  uint32_t raw_ = 0;
};

// Parses `Class(sys/inst)` or `Class(sys/inst)#mbx`; the class by name or as a number
// (`Class0x42(0/1)` and `66(0/1)` are accepted). nullopt on malformed text.
[[nodiscard]] std::optional<Address> parse_address(std::string_view text) noexcept;

// The framework's own class ids. A component class's id is declared with the class
// (rack_add_class in its folder; rack/components/class_ids.h has the tree's): tims/
// knows no component class, only the names the registry gives it
// (register_class_name).
namespace classes {
inline constexpr uint8_t kExecutor = 0x01;   // rackd itself
inline constexpr uint8_t kTool = 0x02;       // rackctl, gdos and other tools
inline constexpr uint8_t kFirstUser = 0x80;  // from here up: free for classes outside the tree
}  // namespace classes

// Name of a class id (as registered), or nullptr when unknown. RT-safe.
[[nodiscard]] const char* class_name(uint8_t class_id) noexcept;
// Class id of a name, or nullopt. RT-safe.
[[nodiscard]] std::optional<uint8_t> class_id(std::string_view name) noexcept;
// Registers a class's name (the registry does, from each class declaration). Not RT-safe;
// call before tasks start. false when id or name is taken, or id is 0, 1, 2 or 255.
bool register_class_name(uint8_t class_id, std::string_view name);

}  // namespace rack::tims
