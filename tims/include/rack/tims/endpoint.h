// A task's TiMS endpoint: its reply mailbox, a sequence counter and the router.
// call() is RACK's RPC: send a request, wait for the reply whose source and sequence
// number match; anything else that arrives in the reply mailbox meanwhile is a stale
// reply of an earlier, timed-out call: it is discarded and counted.
//
// Real-time contract: every method is RT-safe (no allocation; blocking only in
// call(), bounded by its timeout).
// Thread-safety: one task owns an endpoint.
#pragma once

#include <cstdint>
#include <span>

#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"

namespace rack::tims {

enum class CallStatus : uint8_t {
  kOk,          // a reply arrived (its type may still be ERROR or NOT_AVAILABLE)
  kTimeout,     // no matching reply within the timeout
  kSendFailed,  // the request could not be queued
  kTooSmall,    // the reply did not fit the buffer
  kClosed,      // the endpoint's mailbox was closed (shutdown)
};
[[nodiscard]] const char* describe(CallStatus s) noexcept;

struct CallResult {
  CallStatus status = CallStatus::kTimeout;
  MessageHeader reply{};            // valid when status == kOk
  std::span<const std::byte> body;  // into the caller's buffer
  [[nodiscard]] bool ok() const noexcept { return status == CallStatus::kOk && reply.type == msg::kOk; }
};

// RPC over an unreliable link (TiMS/LCM loses datagrams): how long to wait for each
// attempt, and how many attempts. A call is retried only when no reply arrived in
// time; never after a reply (ERROR and NOT_AVAILABLE are answers too). Each attempt
// carries a new sequence number, so a late reply to an earlier attempt is discarded
// as stale. Meant for idempotent requests: RACK's generic ones are (ON of an enabled
// component answers OK again, OFF, GET_*, SET_PARAM of the same value, GET_CONT_DATA
// for the same mailbox replaces the listener).
struct RetryPolicy {
  int64_t timeout_ns = 1'000'000'000;  // per attempt
  uint32_t attempts = 1;               // 1: no retry
};

class Endpoint {
 public:
  Endpoint(Router& router, Mailbox& reply_mailbox, uint8_t priority) noexcept
      : router_(router), mailbox_(reply_mailbox), priority_(priority) {}

  [[nodiscard]] Address address() const noexcept { return mailbox_.address(); }
  [[nodiscard]] Mailbox& mailbox() noexcept { return mailbox_; }
  [[nodiscard]] Router& router() noexcept { return router_; }
  [[nodiscard]] uint8_t priority() const noexcept { return priority_; }

  // Request/reply. `buffer` receives the reply (header included). RT-safe.
  CallResult call(Address dest, int8_t type, std::span<const ConstBuffer> body, std::span<std::byte> buffer,
                  int64_t timeout_ns) noexcept;
  CallResult call(Address dest, int8_t type, std::span<std::byte> buffer, int64_t timeout_ns) noexcept {
    return call(dest, type, std::span<const ConstBuffer>{}, buffer, timeout_ns);
  }
  template <typename T>
  CallResult call(Address dest, int8_t type, const T& request, std::span<std::byte> buffer,
                  int64_t timeout_ns) noexcept {
    const ConstBuffer part = buffer_of(request);
    return call(dest, type, std::span<const ConstBuffer>(&part, 1), buffer, timeout_ns);
  }

  // Request/reply with retries on timeout (see RetryPolicy). RT-safe; blocks at most
  // attempts * timeout_ns.
  CallResult call_with_retry(Address dest, int8_t type, std::span<const ConstBuffer> body, std::span<std::byte> buffer,
                             RetryPolicy policy) noexcept;

  // A message that expects no reply (or whose replies the caller reads itself).
  // Returns the sequence number used through `seq_out` when given. RT-safe.
  SendStatus send(Address dest, int8_t type, std::span<const ConstBuffer> body, Address reply_to = Address(),
                  uint8_t* seq_out = nullptr) noexcept;

  // Answers `request` (same sequence number, to its source). RT-safe.
  SendStatus reply(const MessageHeader& request, int8_t type, std::span<const ConstBuffer> body = {}) noexcept;

  [[nodiscard]] uint64_t stale_replies() const noexcept { return stale_; }
  [[nodiscard]] uint64_t retries() const noexcept { return retries_; }

 private:
  Router& router_;
  Mailbox& mailbox_;
  uint8_t priority_;
  uint8_t seq_ = 0;
  uint64_t stale_ = 0;
  uint64_t retries_ = 0;
};

}  // namespace rack::tims
