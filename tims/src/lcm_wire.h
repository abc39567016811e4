// Total decoders of the lcm-gen types that arrive from a network (internal to tims).
//
// lcm-gen's C++ decoders trust their input: a string whose length field is zero or
// negative makes std::string::assign throw std::length_error (one 39-byte datagram
// aborted rackd), and an array count is resized before anything bounds it. Every
// receiver of RACK-RT (the TiMS transport, the GDOS publisher and subscriber, and so
// the tools) decodes these types here instead: each function checks the fingerprint,
// every string (length >= 1, within the buffer, NUL-terminated, no NUL inside) and every count
// (>= 0, and no more elements than the bytes left could hold) before it allocates, and
// fills the same lcm-gen struct as lcm-gen's decoder would. On refusal it returns -1
// and says what and where ("string 'host' at byte 45: length 0"). Never throws.
//
// Also here: LCM's framing of a UDP datagram (lcm_udpm.c), parsed by bounds-checked
// code. Both are plain functions on a byte buffer (fuzz harnesses: tests/fuzz/).
//
// Real-time contract: not RT-safe (they allocate the decoded strings); called from
// receive threads and tools. Thread-safety: reentrant.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/gdos_batch.hpp"
#include "rack_lcm/gdos_listener.hpp"
#include "rack_lcm/host_announce.hpp"

namespace rack::tims::wire_lcm {

// Smallest encoded array elements (fixed fields, empty strings with length and NUL).
inline constexpr std::size_t kMinComponentInfoBytes = 4 + 5 + 5;
inline constexpr std::size_t kMinGdosRecordBytes = 8 + 8 + 4 + 5 + 1 + 4 + 5;

// Each returns the bytes used (the rest may be an authentication trailer), or -1 with
// `why` set. `size` is the payload (after LCM's framing).
[[nodiscard]] int decode(const uint8_t* d, std::size_t size, rack_lcm::host_announce& out, std::string& why) noexcept;
[[nodiscard]] int decode(const uint8_t* d, std::size_t size, rack_lcm::discover_request& out,
                         std::string& why) noexcept;
[[nodiscard]] int decode(const uint8_t* d, std::size_t size, rack_lcm::gdos_batch& out, std::string& why) noexcept;
[[nodiscard]] int decode(const uint8_t* d, std::size_t size, rack_lcm::gdos_listener& out, std::string& why) noexcept;

// Whether `s` holds a C0 control character or DEL (names from the network are shown on
// terminals; a host file cannot hold them).
[[nodiscard]] inline bool has_control(std::string_view s) noexcept {
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c == 0x7F) return true;
  }
  return false;
}

// LCM's framing of one UDP datagram: "LC02" (a whole message: magic, sequence number,
// channel NUL-terminated, payload) or "LC03" (a fragment of a message above about
// 64 KB: magic, sequence number, message size, fragment offset, fragment number,
// fragment count; the first fragment has the channel). RACK-RT never sends fragments
// (TiMS chunks its messages itself, GDOS batches and announcements stay far below
// 64 KB) and refuses them: LCM 1.3's own reassembly trusts its input.
inline constexpr uint32_t kLcmShortMagic = 0x4c433032;     // "LC02"
inline constexpr uint32_t kLcmFragmentMagic = 0x4c433033;  // "LC03"
inline constexpr std::size_t kLcmMaxChannel = 63;          // LCM_MAX_CHANNEL_NAME_LENGTH

struct LcmDatagram {
  enum Kind : uint8_t {
    kMessage,   // a whole message: channel and payload set
    kFragment,  // an LCM fragment (refused by every RACK-RT receiver, counted)
    kInvalid,   // not LCM: `why` says what
  } kind = kInvalid;
  uint32_t sequence = 0;
  std::string_view channel;  // points into the datagram
  const uint8_t* payload = nullptr;
  std::size_t payload_size = 0;
  const char* why = "";  // kInvalid: a static text
};
[[nodiscard]] LcmDatagram parse_datagram(const uint8_t* d, std::size_t size) noexcept;

}  // namespace rack::tims::wire_lcm
