// A TiMS mailbox: preallocated fixed slots of fixed size, read in priority order
// (higher priority first, FIFO within a priority).
//
// When every slot is taken, the oldest message of the lowest priority present is
// dropped if that priority is not above the new message's; otherwise the send fails.
// Every drop and every refusal is counted.
//
// Why a mutex and not a lock-free queue: priority order and the drop policy need a
// consistent view of all slots. The mutex has priority inheritance and guards only
// slot bookkeeping (O(slots), no copies): a sender reserves a slot, copies outside
// the lock, then commits; a reader does the same in reverse. A waiter is therefore
// delayed by at most one bookkeeping section of a boosted holder.
//
// Real-time contract: after construction, every method is RT-safe (no allocation,
// PI lock only, blocking only where a timeout says so).
// Thread-safety: any number of senders; one reader (peek/peek_end are single-reader).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <span>

#include "rack/rt/pi_mutex.h"
#include "rack/tims/message.h"

namespace rack::tims {

class TrustedSources;
class Mailbox;

// Told of every message the router delivers into a mailbox, in the sender's thread,
// after the message is queued and no lock is held. A stepped executor
// (rack/core/stepper.h) serves a component's command mailbox this way, so that a
// request is answered before the sender waits for the reply; nothing else sets one.
class DeliveryHook {
 public:
  virtual ~DeliveryHook() = default;
  virtual void delivered(Mailbox& mailbox) noexcept = 0;
};

struct ConstBuffer {
  const void* data = nullptr;
  std::size_t size = 0;
};

template <typename T>
[[nodiscard]] ConstBuffer buffer_of(const T& value) noexcept {
  return ConstBuffer{&value, sizeof(T)};
}

enum class SendStatus : uint8_t {
  kOk,
  kOkDroppedOlder,  // delivered; an older message of lower or equal priority was dropped
  kFull,            // refused: every queued message has a higher priority
  kTooLarge,        // the message does not fit a slot
  kClosed,          // the mailbox is shutting down
  kNotAvailable,    // (router) no such mailbox; a request was answered NOT_AVAILABLE
  kDenied,          // (router) refused by access control (a request was answered ERROR), or
                    // by a data mailbox's TrustedSources (a request: NOT_AVAILABLE)
};
[[nodiscard]] const char* describe(SendStatus s) noexcept;
[[nodiscard]] constexpr bool delivered(SendStatus s) noexcept {
  return s == SendStatus::kOk || s == SendStatus::kOkDroppedOlder;
}

enum class RecvStatus : uint8_t {
  kOk,
  kTimeout,   // nothing arrived before the timeout
  kEmpty,     // non-blocking receive found nothing
  kTooSmall,  // the message did not fit the buffer: it was consumed and counted
  kClosed,    // the mailbox was closed (shutdown)
};

struct MailboxCounters {
  uint64_t sent = 0;
  uint64_t received = 0;
  uint64_t dropped = 0;    // queued messages dropped to make room
  uint64_t refused = 0;    // sends refused because full
  uint64_t too_large = 0;  // sends refused because larger than a slot
  uint64_t truncated = 0;  // receives whose buffer was too small
  uint64_t denied = 0;     // messages for it that access control refused (rack/tims/access.h)
};

class Mailbox {
 public:
  // timeout values for receive/peek/wait
  static constexpr int64_t kForever = -1;
  static constexpr int64_t kNonBlocking = 0;

  // Allocates `slots` slots of `slot_size` bytes (header included). Not RT-safe.
  Mailbox(Address address, uint32_t slots, uint32_t slot_size);
  ~Mailbox();
  Mailbox(const Mailbox&) = delete;
  Mailbox& operator=(const Mailbox&) = delete;

  [[nodiscard]] Address address() const noexcept { return address_; }
  [[nodiscard]] uint32_t slot_size() const noexcept { return slot_size_; }
  [[nodiscard]] uint32_t slot_count() const noexcept { return slot_count_; }

  // Queues header + body parts (header.length must equal 16 + sum of parts). Never
  // blocks beyond the bookkeeping lock. RT-safe.
  SendStatus try_send(const MessageHeader& header, std::initializer_list<ConstBuffer> body) noexcept;
  SendStatus try_send(const MessageHeader& header, std::span<const ConstBuffer> body) noexcept;
  // Queues a complete message whose header (host byte order) is at the start. RT-safe.
  SendStatus try_send_bytes(std::span<const std::byte> message) noexcept;

  struct Received {
    RecvStatus status = RecvStatus::kEmpty;
    MessageHeader header{};
    std::size_t length = 0;  // bytes copied (header included)
  };
  // Copies the next message (header included) into `buffer`. timeout_ns: kForever,
  // kNonBlocking or a relative timeout in ns. RT-safe.
  Received receive(std::span<std::byte> buffer, int64_t timeout_ns) noexcept;

  struct Peeked {
    RecvStatus status = RecvStatus::kEmpty;
    const MessageHeader* header = nullptr;  // in the slot; valid until peek_end()
    std::span<const std::byte> body;        // in the slot; valid until peek_end()
  };
  // Zero-copy: the next message stays in its slot until peek_end(). One peek at a
  // time. RT-safe.
  Peeked peek(int64_t timeout_ns) noexcept;
  void peek_end() noexcept;

  // Waits until a message is queued (without taking it). true: a message is there.
  bool wait(int64_t timeout_ns) noexcept;
  // Wakes the reader without a message (wait() and receive() return). RT-safe.
  void wake() noexcept;

  // Refuses further sends and wakes the reader; receives drain what is queued, then
  // return kClosed. reopen() accepts messages again. RT-safe.
  void close() noexcept;
  void reopen() noexcept;

  [[nodiscard]] uint32_t queued() const noexcept;
  [[nodiscard]] MailboxCounters counters() const noexcept;
  // Counts a message for this mailbox that access control refused (the router calls
  // it). RT-safe, lock-free.
  void count_denied() noexcept { denied_.fetch_add(1, std::memory_order_relaxed); }
  // Whom this mailbox trusts (rack/tims/trusted_sources.h): the router refuses every
  // message for it that `trusted` refuses, before it takes a slot. nullptr (default):
  // the router delivers from anyone. Set before traffic flows; `trusted` outlives the
  // mailbox's registration. Not RT-safe to set; trusted_sources() is (lock-free).
  void set_trusted_sources(TrustedSources* trusted) noexcept { trusted_.store(trusted, std::memory_order_release); }
  [[nodiscard]] TrustedSources* trusted_sources() const noexcept { return trusted_.load(std::memory_order_acquire); }
  // The hook the router calls after each delivery here (nullptr: none, the default).
  // Set before traffic flows; `hook` outlives its use. Any thread; RT-safe (atomic).
  void set_delivery_hook(DeliveryHook* hook) noexcept { hook_.store(hook, std::memory_order_release); }
  [[nodiscard]] DeliveryHook* delivery_hook() const noexcept { return hook_.load(std::memory_order_acquire); }
  // A reply mailbox (an endpoint's): the router refuses every request for it, silently
  // (a reply mailbox answers nothing, and an answer would let a flood reflect), and
  // counts it here. Set before traffic flows. RT-safe, lock-free.
  void set_replies_only(bool on) noexcept { replies_only_.store(on, std::memory_order_relaxed); }
  [[nodiscard]] bool replies_only() const noexcept { return replies_only_.load(std::memory_order_relaxed); }
  void count_refused_request() noexcept { refused_requests_.fetch_add(1, std::memory_order_relaxed); }
  [[nodiscard]] uint64_t refused_requests() const noexcept { return refused_requests_.load(std::memory_order_relaxed); }

 private:
  enum class SlotState : uint8_t { kFree, kWriting, kReady, kReading };
  struct SlotInfo {
    SlotState state = SlotState::kFree;
    uint8_t priority = 0;
    uint64_t order = 0;
  };

  int64_t deadline_for(int64_t timeout_ns) const noexcept;
  int find_next_locked() const noexcept;  // highest priority, oldest; -1 if none
  // Waits (lock held) for a ready slot; returns its index or -1 with `status` set.
  int wait_ready_locked(int64_t timeout_ns, RecvStatus& status) noexcept;
  std::byte* slot_data(int index) noexcept { return storage_.get() + static_cast<std::size_t>(index) * slot_size_; }
  void free_slot(int index) noexcept;

  Address address_;
  uint32_t slot_count_;
  uint32_t slot_size_;
  std::unique_ptr<std::byte[]> storage_;
  std::unique_ptr<SlotInfo[]> slots_;
  mutable rt::PiMutex mutex_;
  rt::PiCondVar ready_cv_;
  uint64_t next_order_ = 0;
  uint32_t ready_count_ = 0;
  uint32_t wakeups_ = 0;  // pending wake() calls
  bool closed_ = false;
  int peeked_ = -1;

  // Counters: written under the mutex, read lock-free by tools (relaxed: statistics).
  std::atomic<uint64_t> sent_{0}, received_{0}, dropped_{0}, refused_{0}, too_large_{0}, truncated_{0};
  std::atomic<uint64_t> denied_{0};                // relaxed: a statistic, outside the mutex
  std::atomic<TrustedSources*> trusted_{nullptr};  // release/acquire: the table is built before
  std::atomic<DeliveryHook*> hook_{nullptr};       // release/acquire: the hook is built before
  std::atomic<bool> replies_only_{false};          // relaxed: set before traffic flows
  std::atomic<uint64_t> refused_requests_{0};      // relaxed: a statistic
};

}  // namespace rack::tims
