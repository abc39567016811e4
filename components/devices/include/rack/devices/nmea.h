// NMEA 0183 sentence parser for GNSS receivers: GGA, RMC, GSA, VTG from any talker
// (GP, GN, GL, GA, BD). Bytes go in as they come from the serial port; complete,
// checksum-verified sentences update a fix. Everything else is counted, never
// trusted: a sentence without '$', longer than kMaxSentence, with a wrong or missing
// checksum, with a field that is not a number where one must be, or of a type not
// listed, changes nothing.
//
// Real-time contract: feed(), reset() and the accessors are RT-safe (fixed buffers,
// no allocation, no locale-dependent parsing).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace rack::devices {

struct NmeaFix {
  double latitude_deg = 0.0;   // + north
  double longitude_deg = 0.0;  // + east
  double altitude_m = 0.0;     // above mean sea level (GGA)
  double geoid_separation_m = 0.0;
  double speed_mps = 0.0;   // over ground (RMC/VTG)
  double course_deg = 0.0;  // over ground, clockwise from true north
  double hdop = 0.0, pdop = 0.0, vdop = 0.0;
  int64_t utc_ns = 0;          // UTC of the fix: date (RMC) + time; 0 until a date was seen
  int64_t time_of_day_ns = 0;  // UTC time of day of the last GGA/RMC
  uint8_t quality = 0;         // GGA: 0 none, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning
  uint8_t mode = 1;            // GSA: 1 no fix, 2 2D, 3 3D
  uint8_t satellites = 0;      // GGA: used in the fix
  bool rmc_valid = false;      // RMC status A
};

struct NmeaCounters {
  uint64_t sentences = 0;  // accepted
  uint64_t checksum_errors = 0;
  uint64_t malformed = 0;      // bad structure or field
  uint64_t overlong = 0;       // no line end within kMaxSentence
  uint64_t unknown = 0;        // valid but not GGA/RMC/GSA/VTG
  uint64_t garbage_bytes = 0;  // bytes outside any sentence
};

class NmeaParser {
 public:
  static constexpr std::size_t kMaxSentence = 96;  // NMEA says 82; some receivers exceed it

  enum class Sentence : uint8_t { kNone, kGga, kRmc, kGsa, kVtg };

  // Feeds bytes; returns the number of sentences accepted. `on_sentence` (may be null)
  // is called for each accepted one.
  using Callback = void (*)(void* user, Sentence s);
  std::size_t feed(std::span<const uint8_t> bytes, Callback on_sentence = nullptr, void* user = nullptr) noexcept;
  void reset() noexcept;  // drop a partial sentence (after a reconnect)

  [[nodiscard]] const NmeaFix& fix() const noexcept { return fix_; }
  [[nodiscard]] const NmeaCounters& counters() const noexcept { return counters_; }

  // Parses one complete sentence ("$...*HH", without CR LF). Public for tests.
  Sentence parse_sentence(const char* s, std::size_t len) noexcept;
  // The checksum of the characters between '$' and '*'. RT-safe.
  [[nodiscard]] static uint8_t checksum(const char* body, std::size_t len) noexcept;

 private:
  NmeaFix fix_;
  NmeaCounters counters_;
  char line_[kMaxSentence + 1] = {};
  std::size_t len_ = 0;
  bool in_sentence_ = false;
  bool overflowed_ = false;
  int64_t date_ns_ = 0;  // UTC midnight of the last RMC date
};

}  // namespace rack::devices
