// Whom a data mailbox trusts: the sources a consumer's input mailbox accepts.
//
// A data component's input mailbox (DataComponentBase, mailbox #3) exists to receive
// the samples of the producers it subscribed to (GET_CONT_DATA). The router checks
// every message for such a mailbox against its TrustedSources before it takes a slot
// (Router::send and Router::deliver_local, after access control):
//
//   - a request (type > 0) is never valid in a data mailbox, from anyone: refused
//     (kRequest) and answered NOT_AVAILABLE, as RACK answers a request to a mailbox
//     that does not serve requests, at most kAnswersPerSecond times a second (a flood
//     of requests must not become a flood of replies); never a state change of the
//     component;
//   - a reply or notification (DATA, ERROR, CONT_DATA, ...) is accepted when its
//     source's component (system/class/instance, any local mailbox) is a producer in
//     the table, or is the owner itself (a component may wake its own data task);
//   - one from a producer retired (unsubscribed) less than kLateGraceNs ago is a late
//     message in flight: refused silently and counted as late, not as forged;
//   - anything else is forged: refused and counted, with its source and type kept
//     for the owner's log line (bounded rate, the owner's data task logs it).
// Refused messages never reach the mailbox: a flood cannot push a producer's samples
// out, nor wake the consumer's data task.
//
// The table is fixed (kCapacity producers; no allocation after construction). Source
// addresses of messages from other hosts are vouched for by the transport, which drops
// a packet whose source is not owned by the host that sent it (LcmTransport: forged).
//
// Real-time contract: everything is RT-safe and lock-free (no allocation, no system
// call but the vDSO clock the caller reads).
// Thread-safety: trust()/retire()/clear() from ONE writer (the owner's command task,
// from on()/off()); check(), trusts() and counters() from any thread at once. A check
// that races a change of the same entry may take that one message by either rule.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "rack/tims/message.h"

namespace rack::tims {

class TrustedSources {
 public:
  static constexpr std::size_t kCapacity = 8;             // producers per consumer
  static constexpr int64_t kLateGraceNs = 2'000'000'000;  // in-flight after unsubscribe
  static constexpr int64_t kAnswersPerSecond = 10;        // NOT_AVAILABLE answers

  enum class Verdict : uint8_t {
    kAccept,   // from a trusted producer (or the owner): deliver
    kRequest,  // a request: refused (the router answers NOT_AVAILABLE, rate-limited)
    kForged,   // not from a producer this consumer subscribed to: refused
    kLate,     // from a producer retired less than kLateGraceNs ago: refused quietly
  };

  struct Counters {
    uint64_t forged = 0;       // refused: not from a trusted producer
    uint64_t requests = 0;     // refused: a request sent into the data mailbox
    uint64_t late = 0;         // refused: a retired producer's message still in flight
    uint32_t last_source = 0;  // the last forged message or request: its source
    int8_t last_type = 0;      // and its type
  };

  // `owner`: the consumer's component address (its own messages are accepted).
  explicit TrustedSources(Address owner) noexcept : owner_(owner.component().raw()) {}
  TrustedSources(const TrustedSources&) = delete;
  TrustedSources& operator=(const TrustedSources&) = delete;

  // Trusts `producer`'s component (again). false: the table is full (every entry
  // trusted, or retired less than kLateGraceNs ago). Writer only. RT-safe.
  [[nodiscard]] bool trust(Address producer, int64_t now_ns) noexcept;
  // No longer trusts `producer`: its messages of the next kLateGraceNs are late, later
  // ones forged. Writer only. RT-safe.
  void retire(Address producer, int64_t now_ns) noexcept;
  // Forgets every producer (messages from them are forged from now on). Writer only.
  void clear() noexcept;
  // true while `producer`'s component is trusted. Any thread, RT-safe.
  [[nodiscard]] bool trusts(Address producer) const noexcept;
  // Decides on one message for the mailbox and counts a refusal. Any thread, RT-safe.
  [[nodiscard]] Verdict check(const MessageHeader& h, int64_t now_ns) noexcept;
  // true when a refused request may be answered now (GCRA: kAnswersPerSecond, burst
  // as many). Any thread, RT-safe, lock-free.
  [[nodiscard]] bool may_answer(int64_t now_ns) noexcept;
  [[nodiscard]] Counters counters() const noexcept;

 private:
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  struct Entry {
    // The producer's component address (kEmpty: unused). A writer sets retired_ns
    // before it publishes a new source (release), so a reader that sees the source
    // (acquire) sees its state.
    std::atomic<uint32_t> source{kEmpty};
    std::atomic<int64_t> retired_ns{0};  // 0: trusted; else when it was retired
  };
  [[nodiscard]] Entry* find(uint32_t component) noexcept;

  uint32_t owner_;
  std::array<Entry, kCapacity> entries_{};
  // Statistics and the last refusal (relaxed: independent counters, read by tools).
  std::atomic<uint64_t> forged_{0}, requests_{0}, late_{0};
  std::atomic<uint32_t> last_source_{0};
  std::atomic<int8_t> last_type_{0};
  std::atomic<int64_t> answer_tat_{0};  // GCRA of NOT_AVAILABLE answers
};

[[nodiscard]] const char* describe(TrustedSources::Verdict v) noexcept;

}  // namespace rack::tims
