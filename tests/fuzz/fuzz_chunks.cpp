// libFuzzer harness: the TiMS/LCM chunk reassembler on its own (ChunkReassembler,
// tims/src/lcm_transport_chunks.h): tims_packet payloads as a network delivers them,
// in any order, duplicated, cut short, with time passing. One input is a sequence of
// steps: a byte (bit 0: expire every slot instead of a packet; bit 1: the receiver
// does not want the next message it is asked about), then for a packet a 2-byte
// big-endian length and that many bytes. Checked: every message handed on lies within
// the limits (a TiMS header at least, max_message_bytes at most); a refusal is always
// counted as a malformed TiMS packet; no more messages come out than packets went in.
// Build: this file linked with rack::tims and the lcm-gen headers (the reassembler is
// internal to tims; its header is read from tims/src). Seeds: tests/fuzz/corpus/chunks/
// (one holds a 60 KB chunk: -max_len=65536 or more).
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.h"
#include "lcm_transport_chunks.h"
#include "rack/rt/clock.h"
#include "rack/tims/message.h"

namespace {

using rack::tims::ChunkLimits;

constexpr ChunkLimits kLimits{256 * 1024, 2, 1'000'000'000};

struct Sink final : rack::tims::MessageSink {
  bool want = true;
  uint64_t messages = 0;
  bool wants(const std::byte*, std::size_t) override { return want; }
  void take_message(std::byte* msg, uint32_t len, int64_t, int32_t, int8_t) override {
    FUZZ_CHECK(msg != nullptr);
    FUZZ_CHECK(len >= sizeof(rack::tims::MessageHeader));
    FUZZ_CHECK(len <= kLimits.max_message_bytes);
    ++messages;
  }
};

struct World {
  rack::tims::TransportStats stats;
  rack::tims::lcm_rx::RateLimitedWarn warn{[](const std::string&) {}};
  rack::tims::NetworkLog log{stats, warn, "fuzz", "memq://"};
  Sink sink;
  rack::tims::ChunkReassembler reassembler{0x5eed, kLimits, log, sink};
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  static World* world = new World();  // its buffers are allocated once, as in the transport
  int64_t now = rack::rt::monotonic_ns();
  for (std::size_t at = 0; at < size;) {
    const uint8_t op = data[at++];
    world->sink.want = (op & 2) == 0;
    if ((op & 1) != 0) {
      now += kLimits.timeout_ns + 1;
      world->reassembler.expire(now);
      continue;
    }
    if (at + 2 > size) break;
    const std::size_t len = (std::size_t{data[at]} << 8) | data[at + 1];
    at += 2;
    const std::size_t n = len < size - at ? len : size - at;
    world->reassembler.on_packet(data + at, n, "TIMS");
    at += n;
  }
  const rack::tims::TransportCounters c = world->stats.snapshot();
  FUZZ_CHECK(c.malformed == c.malformed_packet);
  FUZZ_CHECK(world->sink.messages <= c.packets_in);
  // Whatever is still being reassembled is forgotten before the next input.
  world->reassembler.expire(now + 2 * kLimits.timeout_ns);
  return 0;
}
