// The TiMS header as a receiver decodes it (rack/tims/message.h): a datagram or a
// mailbox slot of any length and either byte order. Properties: decode_header() never
// reads past the bytes it is given; a header it accepts has a length equal to the
// bytes received (so body_length() cannot wrap) and known flags only; encoding an
// accepted header in either byte order and decoding it again gives the same header.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "fuzz_support.h"
#include "rack/tims/address.h"
#include "rack/tims/message.h"

using namespace rack::tims;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data), size);
  MessageHeader h;
  const MessageError e = decode_header(bytes, h);
  FUZZ_CHECK(describe(e) != nullptr);
  if (e != MessageError::kOk) {
    FUZZ_CHECK(size < sizeof(MessageHeader) || e != MessageError::kTruncatedHeader);
    return 0;
  }
  FUZZ_CHECK(size >= sizeof(MessageHeader));
  FUZZ_CHECK(h.length == size);
  FUZZ_CHECK(h.body_length() == size - sizeof(MessageHeader));
  FUZZ_CHECK(((h.flags & kFlagHeaderLittleEndian) != 0) == kHostLittleEndian);  // normalised
  FUZZ_CHECK((h.flags & ~(kFlagHeaderLittleEndian | kFlagBodyLittleEndian)) == 0);
  // What a receiver does next with it: names for logs, request or not, byte order.
  (void)msg::name(h.type);
  (void)h.is_request();
  (void)body_is_native(h);
  (void)h.destination().str();
  (void)h.source().component().str();
  // Round trip in both byte orders, body unchanged.
  std::vector<std::byte> again(bytes.begin(), bytes.end());
  for (const bool little : {true, false}) {
    encode_header(h, little, again.data());
    MessageHeader h2;
    FUZZ_CHECK(decode_header(again, h2) == MessageError::kOk);
    FUZZ_CHECK(std::memcmp(&h, &h2, sizeof h) == 0);
  }
  return 0;
}
