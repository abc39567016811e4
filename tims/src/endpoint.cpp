#include "rack/tims/endpoint.h"

#include "rack/rt/clock.h"

namespace rack::tims {

const char* describe(CallStatus s) noexcept {
  switch (s) {
    case CallStatus::kOk: return "ok";
    case CallStatus::kTimeout: return "timed out";
    case CallStatus::kSendFailed: return "request could not be sent";
    case CallStatus::kTooSmall: return "reply larger than the buffer";
    case CallStatus::kClosed: return "closed";
  }
  return "unknown";
}

SendStatus Endpoint::send(Address dest, int8_t type, std::span<const ConstBuffer> body, Address reply_to,
                          uint8_t* seq_out) noexcept {
  std::size_t len = 0;
  for (const auto& p : body) len += p.size;
  const uint8_t seq = ++seq_;
  if (seq_out != nullptr) *seq_out = seq;
  const Address src = reply_to == Address() ? mailbox_.address() : reply_to;
  const MessageHeader h = make_header(dest, src, type, priority_, seq, len);
  return router_.send(h, body);
}

SendStatus Endpoint::reply(const MessageHeader& request, int8_t type, std::span<const ConstBuffer> body) noexcept {
  std::size_t len = 0;
  for (const auto& p : body) len += p.size;
  const MessageHeader h = make_reply_header(request, type, len);
  return router_.send(h, body);
}

CallResult Endpoint::call(Address dest, int8_t type, std::span<const ConstBuffer> body, std::span<std::byte> buffer,
                          int64_t timeout_ns) noexcept {
  CallResult result;
  uint8_t seq = 0;
  const SendStatus sent = send(dest, type, body, Address(), &seq);
  if (!delivered(sent) && sent != SendStatus::kNotAvailable && sent != SendStatus::kDenied) {
    result.status = CallStatus::kSendFailed;
    return result;
  }
  // kNotAvailable, kDenied: the router already queued a NOT_AVAILABLE or ERROR reply
  // for us; read it.
  // The real clock: the wait below is the kernel's (a virtual clock does not move while we wait).
  const int64_t deadline = rt::os_monotonic_ns() + timeout_ns;
  for (;;) {
    const int64_t left = deadline - rt::os_monotonic_ns();
    if (left <= 0) {
      result.status = CallStatus::kTimeout;
      return result;
    }
    const auto r = mailbox_.receive(buffer, left);
    switch (r.status) {
      case RecvStatus::kOk: break;
      case RecvStatus::kTooSmall:
        if (r.header.seq == seq && r.header.source().component() == dest.component()) {
          result.status = CallStatus::kTooSmall;
          return result;
        }
        ++stale_;
        continue;
      case RecvStatus::kClosed: result.status = CallStatus::kClosed; return result;
      case RecvStatus::kTimeout:
      case RecvStatus::kEmpty: continue;  // deadline re-checked above
    }
    // A reply comes from the mailbox we asked (or, for NOT_AVAILABLE, the router
    // answers in its name), with our sequence number.
    if (r.header.seq == seq && r.header.source() == dest && !r.header.is_request()) {
      result.status = CallStatus::kOk;
      result.reply = r.header;
      result.body = std::span<const std::byte>(buffer.data() + sizeof(MessageHeader), r.length - sizeof(MessageHeader));
      return result;
    }
    ++stale_;
  }
}

CallResult Endpoint::call_with_retry(Address dest, int8_t type, std::span<const ConstBuffer> body,
                                     std::span<std::byte> buffer, RetryPolicy policy) noexcept {
  CallResult r;
  const uint32_t attempts = policy.attempts == 0 ? 1 : policy.attempts;
  for (uint32_t i = 0; i < attempts; ++i) {
    if (i > 0) ++retries_;
    r = call(dest, type, body, buffer, policy.timeout_ns);
    if (r.status != CallStatus::kTimeout) return r;
  }
  return r;
}

}  // namespace rack::tims
