// libFuzzer harness for the task timeline's request decoders
// (rack/core/trace_session.h: decode_start, decode_read), which read TRACE_START and
// TRACE_READ bodies from the network (rackctl trace, or anyone on the bus).
// Byte 0 chooses the decoder (bit 0) and the byte order (bit 1); the rest is the body.
// Both must answer ok with no error, or an error that says what is wrong; never crash,
// throw or read past the body.
//
// Seeds: tests/fuzz/corpus/trace_request/ (a start for "all", one with names, a read,
// bodies one byte short).
#include <cstddef>
#include <cstdint>
#include <span>

#include "rack/core/trace_session.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const bool read = (data[0] & 1u) != 0;
  const bool swapped = (data[0] & 2u) != 0;
  const std::span<const std::byte> body(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  if (read) {
    const rack::trace::DecodedRead d = rack::trace::decode_read(body, swapped);
    if (d.ok == !d.error.empty()) __builtin_trap();
  } else {
    const rack::trace::DecodedStart d = rack::trace::decode_start(body, swapped);
    if (d.ok == !d.error.empty()) __builtin_trap();
    if (d.ok) {
      for (const auto& n : d.names) {
        if (n.size() >= sizeof(rack::trace::TraceStartRequest::names)) __builtin_trap();
      }
    }
  }
  return 0;
}
