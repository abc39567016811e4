// The TiMS/LCM wire (internal to tims): the channel names, the byte layout of a
// tims_packet (tims/lcm/rack_tims.lcm) and the big-endian helpers that read and write
// it. Shared by the transport's parts (lcm_transport_impl.h lists them); no state.
//
// Real-time contract: constants and pure functions; nothing here allocates but
// origin_text. Thread-safety: any thread.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "lcm_wire.h"

namespace rack::tims::lcm_detail {

inline constexpr const char* kTimsChannel = "TIMS";
inline constexpr const char* kAnnounceChannel = "TIMS_ANNOUNCE";
inline constexpr const char* kDiscoverChannel = "TIMS_DISCOVER";

// Wire layout of tims_packet (LCM encodes big-endian): 8-byte fingerprint, then the
// fields in declaration order. Offsets of each field:
inline constexpr std::size_t kOffOrigin = 8;
inline constexpr std::size_t kOffRelay = 16;
inline constexpr std::size_t kOffPacketSeq = 24;
inline constexpr std::size_t kOffMessageSeq = 28;
inline constexpr std::size_t kOffTotal = 32;
inline constexpr std::size_t kOffEncoded = 36;
inline constexpr std::size_t kOffOffset = 40;
inline constexpr std::size_t kOffEncoding = 44;
inline constexpr std::size_t kOffHops = 45;
inline constexpr std::size_t kOffSize = 46;
inline constexpr std::size_t kPacketPrefix = 50;
// Bytes of a message per chunk: every LCM datagram stays below LCM's own
// fragmentation limit (about 64 KB), so LCM never reassembles our traffic and a
// receiver knows which message a lost chunk belongs to. Every chunk but the last of a
// message is exactly this long (receivers check it).
inline constexpr uint32_t kChunk = 60000;
// Routers passed before a packet is dropped (a mis-wired fleet must not loop forever).
inline constexpr int8_t kMaxHops = 4;

inline void put_be(uint8_t* p, uint64_t v, int bytes) {
  if (bytes == 8) {
    v = __builtin_bswap64(v);
    std::memcpy(p, &v, 8);
  } else {
    auto w = __builtin_bswap32(static_cast<uint32_t>(v));
    std::memcpy(p, &w, 4);
  }
}
inline uint64_t get_be(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}
inline int64_t get_i64(const uint8_t* p) { return static_cast<int64_t>(get_be(p, 8)); }
inline int32_t get_i32(const uint8_t* p) { return static_cast<int32_t>(static_cast<uint32_t>(get_be(p, 4))); }

using wire_lcm::kLcmFragmentMagic;
using wire_lcm::kLcmShortMagic;

inline std::string origin_text(int64_t origin) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(origin));
  return buf;
}

}  // namespace rack::tims::lcm_detail
