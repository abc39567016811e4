#include "rack/tims/message.h"

#include <cstring>

namespace rack::tims {

namespace {
constexpr uint8_t kKnownFlags = kFlagHeaderLittleEndian | kFlagBodyLittleEndian;
}

const char* msg::name(int8_t type) noexcept {
  switch (type) {
    case kOn: return "ON";
    case kOff: return "OFF";
    case kGetStatus: return "GET_STATUS";
    case kGetData: return "GET_DATA";
    case kGetContData: return "GET_CONT_DATA";
    case kStopContData: return "STOP_CONT_DATA";
    case kGetNextData: return "GET_NEXT_DATA";
    case kGetParam: return "GET_PARAM";
    case kSetParam: return "SET_PARAM";
    case kGetStats: return "GET_STATS";
    case kGetLatency: return "GET_LATENCY";
    case kGetClass: return "GET_CLASS";
    case kGetListeners: return "GET_LISTENERS";
    case kGetTasks: return "GET_TASKS";
    case kOk: return "OK";
    case kError: return "ERROR";
    case kTimeout: return "TIMEOUT";
    case kNotAvailable: return "NOT_AVAILABLE";
    case kEnabled: return "ENABLED";
    case kDisabled: return "DISABLED";
    case kData: return "DATA";
    case kContData: return "CONT_DATA";
    case kParam: return "PARAM";
    case kStats: return "STATS";
    case kLatency: return "LATENCY";
    case kClass: return "CLASS";
    case kListeners: return "LISTENERS";
    case kTasks: return "TASKS";
    default: return nullptr;
  }
}

bool body_is_native(const MessageHeader& h) noexcept {
  return ((h.flags & kFlagBodyLittleEndian) != 0) == kHostLittleEndian;
}

const char* describe(MessageError e) noexcept {
  switch (e) {
    case MessageError::kOk: return "ok";
    case MessageError::kTruncatedHeader: return "truncated header (fewer than 16 bytes)";
    case MessageError::kLengthMismatch: return "length in header differs from bytes received";
    case MessageError::kUnknownFlags: return "reserved header flag bits set";
  }
  return "unknown";
}

MessageError decode_header(std::span<const std::byte> bytes, MessageHeader& out) noexcept {
  if (bytes.size() < sizeof(MessageHeader)) return MessageError::kTruncatedHeader;
  std::memcpy(&out, bytes.data(), sizeof(MessageHeader));
  if ((out.flags & ~kKnownFlags) != 0) return MessageError::kUnknownFlags;
  const bool header_le = (out.flags & kFlagHeaderLittleEndian) != 0;
  if (header_le != kHostLittleEndian) {
    out.dest = bswap(out.dest);
    out.src = bswap(out.src);
    out.length = bswap(out.length);
    out.flags = static_cast<uint8_t>((out.flags & ~kFlagHeaderLittleEndian) |
                                     (kHostLittleEndian ? kFlagHeaderLittleEndian : 0));
  }
  if (out.length != bytes.size()) return MessageError::kLengthMismatch;
  return MessageError::kOk;
}

void encode_header(const MessageHeader& h, bool little_endian, std::byte* out16) noexcept {
  MessageHeader w = h;
  w.flags = static_cast<uint8_t>((h.flags & ~kFlagHeaderLittleEndian) | (little_endian ? kFlagHeaderLittleEndian : 0));
  if (little_endian != kHostLittleEndian) {
    w.dest = bswap(h.dest);
    w.src = bswap(h.src);
    w.length = bswap(h.length);
  }
  std::memcpy(out16, &w, sizeof w);
}

}  // namespace rack::tims
