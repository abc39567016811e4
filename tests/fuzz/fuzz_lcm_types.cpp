// libFuzzer harness: the total decoders of the lcm-gen types that arrive from a network
// (tims/src/lcm_wire.h: host_announce, discover_request, gdos_batch, gdos_listener) and
// LCM's datagram framing. Differential: whatever our decoder accepts, lcm-gen's own
// decoder must accept too, with the same length, and both must re-encode to the same
// bytes (so the two cannot disagree on what a message says). Our decoder must never
// throw (noexcept: a throw ends the fuzzer) and must refuse what lcm-gen's would throw
// on. The first byte picks the decoder; the rest is the payload.
// Build: this file + tims/src/lcm_wire.cpp; include dirs tims/src and the lcm-gen
// headers (${PROJECT_BINARY_DIR}/tims/lcm_gen, target rack_lcm_types); no library.
// Seeds: tests/fuzz/corpus/lcm_types/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "lcm_wire.h"

namespace {

template <typename T>
void check(const uint8_t* d, std::size_t size) {
  T ours;
  std::string why;
  const int used = rack::tims::wire_lcm::decode(d, size, ours, why);
  if (used < 0) {
    if (why.empty()) std::abort();  // every refusal says why
    return;
  }
  if (static_cast<std::size_t>(used) > size) std::abort();
  T theirs;
  const int their_used = theirs.decode(d, 0, static_cast<int>(size));  // safe: ours accepted it
  if (their_used != used) std::abort();
  const int n = ours.getEncodedSize();
  if (n != used || theirs.getEncodedSize() != n) std::abort();
  std::vector<uint8_t> a(static_cast<std::size_t>(n)), b(static_cast<std::size_t>(n));
  if (ours.encode(a.data(), 0, n) != n || theirs.encode(b.data(), 0, n) != n || a != b) std::abort();
  // And the re-encoding is what was received.
  for (int i = 0; i < n; ++i) {
    if (a[static_cast<std::size_t>(i)] != d[i]) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const uint8_t* d = data + 1;
  const std::size_t n = size - 1;
  switch (data[0] % 5) {
    case 0: check<rack_lcm::host_announce>(d, n); break;
    case 1: check<rack_lcm::discover_request>(d, n); break;
    case 2: check<rack_lcm::gdos_batch>(d, n); break;
    case 3: check<rack_lcm::gdos_listener>(d, n); break;
    default: {
      const auto g = rack::tims::wire_lcm::parse_datagram(d, n);
      if (g.kind == rack::tims::wire_lcm::LcmDatagram::kMessage) {
        if (g.payload < d || g.payload + g.payload_size != d + n || g.channel.size() > 63) std::abort();
      }
      break;
    }
  }
  return 0;
}
