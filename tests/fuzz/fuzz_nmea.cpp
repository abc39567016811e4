// NMEA 0183 from a GNSS receiver's serial port (components/devices/src/nmea.cpp): the
// byte stream in the pieces a read() returns, and single sentences as
// parse_sentence() takes them.
//
// Input: byte 0 sets the size of the pieces fed (1..64 bytes, as reads return them);
// the rest is the stream. Properties: feed() counts every sentence it accepts or
// refuses; an accepted fix has finite numbers in range (latitude -90..90, longitude
// -180..180, a quality, mode and satellite count the sentences can carry).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "rack/devices/nmea.h"

using rack::devices::NmeaFix;
using rack::devices::NmeaParser;

namespace {

void check_fix(const NmeaFix& f) {
  FUZZ_CHECK(std::isfinite(f.latitude_deg) && std::fabs(f.latitude_deg) <= 90.0);
  FUZZ_CHECK(std::isfinite(f.longitude_deg) && std::fabs(f.longitude_deg) <= 180.0);
  FUZZ_CHECK(std::isfinite(f.altitude_m) && std::isfinite(f.geoid_separation_m));
  FUZZ_CHECK(std::isfinite(f.speed_mps) && std::isfinite(f.course_deg));
  FUZZ_CHECK(std::isfinite(f.hdop) && std::isfinite(f.pdop) && std::isfinite(f.vdop));
  FUZZ_CHECK(f.mode >= 1 && f.mode <= 3);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const std::size_t piece = 1 + in.byte() % 64;
  NmeaParser p;
  std::size_t accepted = 0;
  while (!in.empty()) {
    accepted += p.feed(
        in.bytes(piece), [](void* user, NmeaParser::Sentence) { check_fix(static_cast<NmeaParser*>(user)->fix()); },
        &p);
  }
  FUZZ_CHECK(accepted == p.counters().sentences);
  check_fix(p.fix());
  // The whole input as one sentence (the parser's own entry point, public for tests).
  NmeaParser q;
  if (size > 0) (void)q.parse_sentence(reinterpret_cast<const char*>(data), size);
  check_fix(q.fix());
  return 0;
}
