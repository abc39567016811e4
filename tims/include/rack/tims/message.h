// The TiMS message: a 16-byte header followed by the body.
//
//   byte 0     flags     bit 0: header is little-endian, bit 1: body is little-endian
//   byte 1     type      int8: > 0 request (expects a reply), <= 0 reply or notification
//   byte 2     priority  uint8: higher is more urgent; mailboxes read in priority order
//   byte 3     seq       uint8: sequence number; a reply carries its request's number
//   bytes 4-7  dest      destination address
//   bytes 8-11 src       source address (where replies go)
//   bytes 12-15 length   total length in bytes, header included
//
// A receiver converts a header whose byte order differs from its own on receipt
// (normalize_header); the body keeps its flag until the component that understands
// the payload converts it (payload types declare how, see rack/tims/payload.h).
//
// Real-time contract: everything here is RT-safe.
#pragma once

#include <bit>

#include "rack/tims/byte_order.h"
#include <cstddef>
#include <cstdint>
#include <span>

#include "rack/tims/address.h"

namespace rack::tims {

struct MessageHeader {
  uint8_t flags = 0;
  int8_t type = 0;
  uint8_t priority = 0;
  uint8_t seq = 0;
  uint32_t dest = 0;
  uint32_t src = 0;
  uint32_t length = 0;  // header + body

  [[nodiscard]] constexpr Address destination() const noexcept { return Address(dest); }
  [[nodiscard]] constexpr Address source() const noexcept { return Address(src); }
  [[nodiscard]] constexpr uint32_t body_length() const noexcept {
    return length - static_cast<uint32_t>(sizeof(MessageHeader));
  }
  [[nodiscard]] constexpr bool is_request() const noexcept { return type > 0; }
};
static_assert(sizeof(MessageHeader) == 16, "TiMS header is 16 bytes on the wire");

inline constexpr uint8_t kFlagHeaderLittleEndian = 0x01;
inline constexpr uint8_t kFlagBodyLittleEndian = 0x02;
inline constexpr bool kHostLittleEndian = std::endian::native == std::endian::little;
// Flags of a message made on this host.
inline constexpr uint8_t kNativeFlags = kHostLittleEndian ? (kFlagHeaderLittleEndian | kFlagBodyLittleEndian) : 0;

// RACK's generic message numbers (DESIGN.md). Tools and tests rely on them.
namespace msg {
// Requests (positive).
inline constexpr int8_t kOn = 1;
inline constexpr int8_t kOff = 2;
inline constexpr int8_t kGetStatus = 3;
inline constexpr int8_t kGetData = 4;
inline constexpr int8_t kGetContData = 6;
inline constexpr int8_t kStopContData = 7;
inline constexpr int8_t kGetNextData = 8;
inline constexpr int8_t kGetParam = 9;
inline constexpr int8_t kSetParam = 10;
inline constexpr int8_t kGetStats = 11;      // RACK-RT: task timing statistics
inline constexpr int8_t kGetLatency = 12;    // RACK-RT: the data task's wake-up latency histogram
inline constexpr int8_t kGetClass = 13;      // RACK-RT: a page of the class description (rack/core/class_description.h)
inline constexpr int8_t kGetListeners = 14;  // RACK-RT: a data component's subscribers (wire::ListenersReply)
inline constexpr int8_t kGetTasks = 15;      // RACK-RT: how its tasks run and its host's networks (wire::TasksReply)
inline constexpr int8_t kFirstClassCommand = 21;
// Executor requests (sent to Executor(sys/host)).
inline constexpr int8_t kExecList = 21;
// Replies and notifications (zero or negative).
inline constexpr int8_t kOk = 0;
inline constexpr int8_t kError = -1;
inline constexpr int8_t kTimeout = -2;
inline constexpr int8_t kNotAvailable = -3;
inline constexpr int8_t kEnabled = -4;
inline constexpr int8_t kDisabled = -5;
inline constexpr int8_t kData = -6;
inline constexpr int8_t kContData = -7;
// RACK-RT: a producer's stream has ended (a replay at the end of its log): no more DATA
// follows while it stays ENABLED. Sent to each listener (no body); a consumer whose
// every input ended is idle, not failing (rack/core/data_component.h "End of stream").
inline constexpr int8_t kEndOfStream = -8;
inline constexpr int8_t kParam = -9;
inline constexpr int8_t kStats = -11;
inline constexpr int8_t kLatency = -12;
inline constexpr int8_t kClass = -13;
inline constexpr int8_t kListeners = -14;
inline constexpr int8_t kTasks = -15;
inline constexpr int8_t kFirstClassReply = -21;
// Name of a generic message number, or nullptr. RT-safe.
[[nodiscard]] const char* name(int8_t type) noexcept;
}  // namespace msg

// Builds a header for a message made on this host. RT-safe.
[[nodiscard]] constexpr MessageHeader make_header(Address dest, Address src, int8_t type, uint8_t priority, uint8_t seq,
                                                  std::size_t body_length) noexcept {
  MessageHeader h;
  h.flags = kNativeFlags;
  h.type = type;
  h.priority = priority;
  h.seq = seq;
  h.dest = dest.raw();
  h.src = src.raw();
  h.length = static_cast<uint32_t>(sizeof(MessageHeader) + body_length);
  return h;
}

// The reply header for `request`: destination is the request's source. RT-safe.
[[nodiscard]] constexpr MessageHeader make_reply_header(const MessageHeader& request, int8_t type,
                                                        std::size_t body_length) noexcept {
  return make_header(request.source(), request.destination(), type, request.priority, request.seq, body_length);
}

[[nodiscard]] bool body_is_native(const MessageHeader& h) noexcept;

enum class MessageError : uint8_t {
  kOk,
  kTruncatedHeader,  // fewer than 16 bytes
  kLengthMismatch,   // header length differs from the bytes received
  kUnknownFlags,     // reserved flag bits set
};
[[nodiscard]] const char* describe(MessageError e) noexcept;

// Reads a header from raw bytes (copy, alignment-safe), converts it to host byte
// order when its flag says otherwise, and checks it against the bytes received.
// RT-safe.
[[nodiscard]] MessageError decode_header(std::span<const std::byte> bytes, MessageHeader& out) noexcept;

// Writes `h` in the given byte order (for tests and foreign peers). RT-safe.
void encode_header(const MessageHeader& h, bool little_endian, std::byte* out16) noexcept;

}  // namespace rack::tims
