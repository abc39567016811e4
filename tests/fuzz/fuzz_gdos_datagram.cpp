// libFuzzer harness: the GDOS subscriber's receive path (what the `gdos` viewer does
// with each UDP datagram: LCM's framing, fragments refused, gdos_batch and
// host_announce decoded, records handed on). GdosSubscriber::handle_datagram, no
// socket (the subscriber is made on an LCM log file written to /dev/null). One input
// is a sequence of datagrams (2-byte big-endian length, then the bytes).
// Build: this file linked with rack::tims (public headers only).
// Seeds: tests/fuzz/corpus/gdos_datagram/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "rack/tims/gdos_lcm.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  static auto* sub = new rack::tims::GdosSubscriber("file:///dev/null?mode=w", rack::tims::kGdosChannel, false, "fuzz");
  std::size_t records = 0;
  const auto sink = [&](const rack::tims::GdosRecord& r) {
    records += 1 + (r.text.size() & 1);  // touch what was decoded
  };
  for (std::size_t at = 0; at + 2 <= size;) {
    const std::size_t len = (std::size_t{data[at]} << 8) | data[at + 1];
    at += 2;
    const std::size_t n = len < size - at ? len : size - at;
    sub->handle_datagram(data + at, n, sink);
    at += n;
  }
  (void)sub->announced_name(0);
  (void)sub->take_warnings();  // bounded: one line per kind per second
  return 0;
}
