// SCIP 2.0 (Hokuyo URG/UTM laser scanners over serial or USB-ACM): command framing,
// the 6-bit character encoding, checksums, and a parser that turns the byte stream
// into complete responses (PP parameters, MD/GD scans).
//
// A response is the echoed command line, a status line, optional data lines and an
// empty line. Every status/data line ends with a checksum character:
// (sum of the line's other bytes & 0x3F) + 0x30. Ranges are 3-character encoded
// (each character carries 6 bits, offset 0x30) and may straddle 64-character lines.
//
// Real-time contract: everything here is RT-safe (fixed buffers, no allocation).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace rack::devices::scip {

inline constexpr std::size_t kMaxSteps = 1440;  // UTM-30LX: 1081 steps; 1440 covers 360 deg at 0.25
inline constexpr std::size_t kMaxBlock = 8192;  // one response (a 1081-step scan is ~3.5 KB)

[[nodiscard]] char checksum(const char* data, std::size_t len) noexcept;
// Appends the 3-character encoding of v (< 2^18). Returns the characters written.
std::size_t encode3(uint32_t v, char* out) noexcept;
[[nodiscard]] uint32_t decode(const char* in, std::size_t chars) noexcept;

struct Parameters {
  uint32_t dmin_mm = 0, dmax_mm = 0;  // valid range
  uint32_t ares = 0;                  // steps per revolution
  uint32_t amin = 0, amax = 0;        // first and last measurable step
  uint32_t afrt = 0;                  // the step straight ahead
  uint32_t scan_rpm = 0;
  bool complete() const noexcept { return ares > 0 && amax > amin && dmax_mm > 0 && scan_rpm > 0; }
};

struct Scan {
  uint32_t first_step = 0, last_step = 0, cluster = 1;
  uint32_t count = 0;
  uint32_t timestamp_ms = 0;  // the sensor's 24-bit millisecond clock
  uint32_t range_mm[kMaxSteps] = {};
};

struct Counters {
  uint64_t responses = 0;
  uint64_t scans = 0;
  uint64_t checksum_errors = 0;
  uint64_t malformed = 0;  // structure wrong, error status, counts that do not add up
  uint64_t overflows = 0;  // a response longer than kMaxBlock (noise without empty lines)
};

class Parser {
 public:
  enum class Event : uint8_t { kNone, kScan, kParameters, kStatus };
  // Feeds bytes; calls `on_event` for each complete, valid response. The scan or
  // parameters are readable through scan()/parameters() during the call.
  using Callback = void (*)(void* user, Event e, const char command[2], const char status[2]);
  std::size_t feed(std::span<const uint8_t> bytes, Callback on_event, void* user) noexcept;
  void reset() noexcept { len_ = 0; }

  [[nodiscard]] const Scan& scan() const noexcept { return scan_; }
  [[nodiscard]] const Parameters& parameters() const noexcept { return params_; }
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }

 private:
  Event parse_block(char command[2], char status[2]) noexcept;

  char block_[kMaxBlock] = {};
  std::size_t len_ = 0;
  Scan scan_;
  Parameters params_;
  Counters counters_;
};

}  // namespace rack::devices::scip
