// SICK CoLa-A (ASCII) telegrams as the LMS1xx/LMS5xx/TiM5xx speak them over TCP
// (port 2111): STX (0x02) "command fields ..." ETX (0x03), fields separated by single
// spaces, numbers in hexadecimal unless signed with +/-. Framing, and a parser for the
// LMDscandata telegram (continuous output "sSN LMDscandata" or the answer "sRA
// LMDscandata") with its 16-bit channels DIST1 and RSSI1.
//
// Angles: SICK's frame has 90 deg straight ahead (an LMS1xx scans -45 .. 225 deg);
// Scan reports SICK's angles, the driver turns them into the robot's (0 ahead).
//
// Real-time contract: everything here is RT-safe (fixed buffers, no allocation).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace rack::devices::cola {

inline constexpr uint8_t kStx = 0x02;
inline constexpr uint8_t kEtx = 0x03;
inline constexpr std::size_t kMaxTelegram = 32 * 1024;
inline constexpr std::size_t kMaxPoints = 1141;  // LMS5xx at 0.1667 deg: 1141

struct Scan {
  uint32_t scan_counter = 0;
  uint32_t scan_frequency_centihz = 0;  // 5000 = 50 Hz
  double start_angle_deg = 0.0;         // SICK frame
  double step_deg = 0.0;
  uint32_t count = 0;
  bool has_rssi = false;
  float range_m[kMaxPoints] = {};
  float rssi[kMaxPoints] = {};
};

struct Counters {
  uint64_t telegrams = 0;
  uint64_t scans = 0;
  uint64_t malformed = 0;      // a field missing or not a number, counts that do not add up
  uint64_t overflows = 0;      // no ETX within kMaxTelegram
  uint64_t garbage_bytes = 0;  // bytes outside STX..ETX
};

class Parser {
 public:
  // Called for each complete telegram (body between STX and ETX, not NUL-terminated);
  // `is_scan` says that scan() now holds a new LMDscandata.
  using Callback = void (*)(void* user, const char* body, std::size_t len, bool is_scan);
  std::size_t feed(std::span<const uint8_t> bytes, Callback on_telegram, void* user) noexcept;
  void reset() noexcept {
    len_ = 0;
    in_ = false;
  }
  [[nodiscard]] const Scan& scan() const noexcept { return scan_; }
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }

 private:
  bool parse_scan(const char* body, std::size_t len) noexcept;

  char buf_[kMaxTelegram] = {};
  std::size_t len_ = 0;
  bool in_ = false;
  Scan scan_;
  Counters counters_;
};

}  // namespace rack::devices::cola
