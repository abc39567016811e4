// TiMS addresses: 32 bits = system (8) | class (8) | instance (8) | local mailbox (8).
// Local mailbox 0 is a component's command mailbox. Printed as `Ladar(0/1)`, or
// `Ladar(0/1)#3` for local mailbox 3.
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

// Ids: the framework's own (kExecutor, kTool); the rest are TRANSITIONAL (tests, tools)
// copies of the class declarations' ids (names: register_class_name, 0x80.. free).
namespace classes {
inline constexpr uint8_t kExecutor = 0x01;  // rackd itself
inline constexpr uint8_t kTool = 0x02;      // rackctl, gdos and other tools
inline constexpr uint8_t kChassis = 0x10;
inline constexpr uint8_t kLadar = 0x11;
inline constexpr uint8_t kCamera = 0x12;
inline constexpr uint8_t kGps = 0x13;
inline constexpr uint8_t kGyro = 0x14;
inline constexpr uint8_t kJoystick = 0x15;
inline constexpr uint8_t kOdometry = 0x16;
inline constexpr uint8_t kServoDrive = 0x17;
inline constexpr uint8_t kPath = 0x18;
inline constexpr uint8_t kPilot = 0x19;
inline constexpr uint8_t kPosition = 0x1A;
inline constexpr uint8_t kScan2d = 0x1B;
inline constexpr uint8_t kScan3d = 0x1C;
inline constexpr uint8_t kObjRecog = 0x1D;
inline constexpr uint8_t kMcl = 0x1E;
inline constexpr uint8_t kGenerator = 0x40;       // demo: periodic producer
inline constexpr uint8_t kMonitor = 0x41;         // demo: consumer with statistics
inline constexpr uint8_t kProbe = 0x42;           // test component whose hooks can fail on demand
inline constexpr uint8_t kModeSwitchDemo = 0x43;  // demo: triggers each mode-switch reason on demand
inline constexpr uint8_t kEvaluator = 0x44;       // simulation: localisation error against the true pose
inline constexpr uint8_t kFirstUser = 0x80;
}  // namespace classes

// Name of a class id ("Ladar"), or nullptr when unknown. RT-safe.
[[nodiscard]] const char* class_name(uint8_t class_id) noexcept;
// Class id of a name, or nullopt. RT-safe.
[[nodiscard]] std::optional<uint8_t> class_id(std::string_view name) noexcept;
// Registers a class's name (the registry does, from each class declaration). Not RT-safe;
// call before tasks start. false when id or name is taken, or id is 0, 1, 2 or 255.
bool register_class_name(uint8_t class_id, std::string_view name);

}  // namespace rack::tims
