// SICK CoLa-A telegrams over TCP (components/devices/src/cola.cpp): the byte stream in
// the pieces a read() returns, with the LMDscandata parser behind it.
//
// Input: byte 0 sets the size of the pieces fed (1..256 bytes); the rest is the stream.
// Properties: a scan the parser reports has at most kMaxPoints points, finite angles,
// finite ranges and intensities; telegrams are counted.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "rack/devices/cola.h"

namespace cola = rack::devices::cola;

namespace {

void on_telegram(void* user, const char* body, std::size_t len, bool is_scan) {
  const auto& p = *static_cast<const cola::Parser*>(user);
  FUZZ_CHECK(body != nullptr || len == 0);
  FUZZ_CHECK(len <= cola::kMaxTelegram);
  if (!is_scan) return;
  const cola::Scan& s = p.scan();
  FUZZ_CHECK(s.count <= cola::kMaxPoints);
  FUZZ_CHECK(std::isfinite(s.start_angle_deg) && std::isfinite(s.step_deg));
  for (uint32_t i = 0; i < s.count; ++i) {
    FUZZ_CHECK(std::isfinite(s.range_m[i]));
    FUZZ_CHECK(std::isfinite(s.rssi[i]));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const std::size_t piece = 1 + in.byte();
  static cola::Parser p;  // 32 KiB buffer + scan: kept between inputs, reset for each
  p = cola::Parser();
  std::size_t telegrams = 0;
  while (!in.empty()) telegrams += p.feed(in.bytes(piece), &on_telegram, &p);
  FUZZ_CHECK(telegrams == p.counters().telegrams);
  return 0;
}
