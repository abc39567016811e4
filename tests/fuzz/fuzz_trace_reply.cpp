// libFuzzer harness for the decoder of TRACE_READ replies (rack/core/trace_session.h:
// decode_chunk), which rackctl trace runs on what the executor, or anyone answering in
// its place, sends back: a TraceChunkHeader and a chunk of the JSON.
// Byte 0: bit 0 chooses the byte order; bits 1-2 how much was read before (0, 16,
// 4096 or 1 GiB bytes: the expected offset); bit 3 whether an earlier chunk announced
// a total (the offset plus 64 KiB). The rest is the reply body.
// The decoder must answer ok with no error or an error that says where; when ok, the
// chunk lies inside the body, at the expected offset, within the announced total.
//
// Seeds: tests/fuzz/corpus/trace_reply/ (recording, a first and a last chunk, an idle
// reply, each byte order, a truncated header, a chunk longer than its reply, a huge total).
#include <cstddef>
#include <cstdint>
#include <span>

#include "rack/core/trace_session.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const bool swapped = (data[0] & 1u) != 0;
  constexpr uint64_t kOffsets[4] = {0, 16, 4096, 1ull << 30};
  const uint64_t offset = kOffsets[(data[0] >> 1) & 3u];
  const uint64_t total = (data[0] & 8u) != 0 ? offset + 65536 : 0;
  const std::span<const std::byte> body(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  const rack::trace::DecodedChunk d = rack::trace::decode_chunk(body, swapped, offset, total);
  if (d.ok == !d.error.empty()) __builtin_trap();
  if (!d.ok) {
    if (d.error.find("byte ") == std::string::npos) __builtin_trap();  // says where
    return 0;
  }
  const auto& h = d.header;
  if (h.state > 2) __builtin_trap();
  if (d.bytes.size() != h.length) __builtin_trap();
  if (!d.bytes.empty() && (d.bytes.data() < body.data() || d.bytes.data() + d.bytes.size() > body.data() + body.size()))
    __builtin_trap();
  if (h.state == static_cast<uint32_t>(rack::trace::TraceState::kReady)) {
    if (h.offset != offset || h.total > rack::trace::kMaxTraceJsonBytes) __builtin_trap();
    if (total != 0 && h.total != total) __builtin_trap();
    if (h.offset + h.length > h.total) __builtin_trap();
  } else if (h.length != 0 || h.remaining_ns < 0) {
    __builtin_trap();
  }
  return 0;
}
