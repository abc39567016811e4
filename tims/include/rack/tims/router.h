// The local TiMS router: every mailbox of this process by address, and the way out
// to other hosts (an uplink mailbox that the LCM transport drains).
//
// Routing rules:
//  - a local mailbox gets the message directly;
//  - an address of another system (robot), or of the tool system (kToolSystem), goes
//    to the uplink when there is one;
//  - an address of this system that is not local goes to the uplink too when the
//    system is shared (set_system_shared: other hosts of this robot may own it; the
//    LCM transport then decides, from discovery, whether to publish it or to answer
//    NOT_AVAILABLE);
//  - otherwise the address is unknown: a request (type > 0) is answered
//    NOT_AVAILABLE to its source, a reply or notification is dropped and counted.
// With access control (set_access), every message for a local mailbox, sent here or
// arrived from the network, is checked first (rack/tims/access.h): a refused request
// is answered ERROR with the reason (at most AccessControl::kRepliesPerSecond per
// rule: a flood is not echoed), a refused reply or notification is dropped;
// both are counted (per rule, and on the mailbox: MailboxCounters::denied).
// A mailbox with TrustedSources (a consumer's data mailbox, rack/tims/trusted_sources.h)
// is checked next: a request is refused and answered NOT_AVAILABLE (rate-limited), a
// reply or notification not from a trusted producer is refused; both are counted by
// the TrustedSources (and in RouterCounters::untrusted), never queued. A request for a
// reply mailbox (Mailbox::set_replies_only) is refused silently and counted there.
// After a local delivery by send(), the mailbox's DeliveryHook, if it has one (a
// stepped executor's command mailboxes only, rack/core/stepper.h), runs in the
// sender's thread; without one the cost is one atomic load.
//
// Real-time contract: find() and send() are RT-safe and lock-free on the look-up
// (a PI-locked mailbox send follows). add()/remove()/set_uplink() are not RT-safe
// and must not race with each other (one set-up thread).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <initializer_list>
#include <span>

#include "rack/tims/access.h"
#include "rack/tims/mailbox.h"

namespace rack::tims {

// System id of tools (rackctl, gdos): they live off-host, behind the uplink.
inline constexpr uint8_t kToolSystem = 255;

struct RouterCounters {
  uint64_t delivered_local = 0;
  uint64_t sent_uplink = 0;
  uint64_t not_available = 0;  // requests to unknown mailboxes (answered NOT_AVAILABLE)
  uint64_t unroutable = 0;     // replies/notifications to unknown mailboxes (dropped)
  uint64_t failed = 0;         // local or uplink send refused (full, too large, closed)
  uint64_t denied = 0;         // refused by access control
  uint64_t untrusted = 0;      // refused by a data mailbox's TrustedSources, or a request
                               // for a reply mailbox
};

class Router {
 public:
  static constexpr std::size_t kCapacity = 2048;  // mailboxes per process

  explicit Router(uint8_t system) noexcept : system_(system) {}
  Router(const Router&) = delete;
  Router& operator=(const Router&) = delete;

  [[nodiscard]] uint8_t system() const noexcept { return system_; }

  // Registers a mailbox. Throws std::invalid_argument naming the address when it is
  // taken, std::length_error when the table is full. Not RT-safe.
  void add(Mailbox& mailbox);
  void remove(Address address) noexcept;
  // Messages for other hosts go to `uplink` (nullptr: none); those longer than its
  // slots go to `large_uplink` when given. Not RT-safe.
  void set_uplink(Mailbox* uplink, Mailbox* large_uplink = nullptr) noexcept;
  // true: other hosts share this system, so a non-local address of it goes to the
  // uplink and deliver_local() leaves unknown addresses to the transport. Not RT-safe.
  void set_system_shared(bool shared) noexcept;
  // Checks every local delivery against `access` (nullptr: none, everything passes).
  // Set before traffic flows; `access` outlives the router's use. Not RT-safe.
  void set_access(AccessControl* access) noexcept;
  [[nodiscard]] AccessControl* access() const noexcept { return access_.load(std::memory_order_acquire); }

  [[nodiscard]] Mailbox* find(Address address) const noexcept;  // RT-safe, lock-free
  [[nodiscard]] bool is_remote(Address address) const noexcept;

  // Routes header + body parts. RT-safe.
  SendStatus send(const MessageHeader& header, std::initializer_list<ConstBuffer> body) noexcept;
  SendStatus send(const MessageHeader& header, std::span<const ConstBuffer> body) noexcept;
  // Routes a complete message whose header is in host byte order. RT-safe.
  SendStatus send_bytes(std::span<const std::byte> message) noexcept;
  // Delivers only to a local mailbox (used for messages that arrived from the uplink,
  // so they are never sent back out). Unknown: a request is answered NOT_AVAILABLE when
  // the address belongs to this system and the system is not shared. RT-safe.
  SendStatus deliver_local(std::span<const std::byte> message) noexcept;

  [[nodiscard]] RouterCounters counters() const noexcept;

 private:
  struct Entry {
    // Key first published (release) after the value, so a reader that sees the key
    // also sees the mailbox pointer.
    std::atomic<uint32_t> key{kEmpty};
    std::atomic<Mailbox*> mailbox{nullptr};
  };
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  static std::size_t slot_of(uint32_t key) noexcept {
    return static_cast<std::size_t>((key * 2654435761u) % kCapacity);
  }
  SendStatus answer_not_available(const MessageHeader& request) noexcept;
  SendStatus route_unknown(const MessageHeader& header) noexcept;
  // true: may be delivered to `local`; false: refused (answered and counted here).
  bool admit(const MessageHeader& header, Mailbox& local, MessageOrigin origin) noexcept;
  // true: `local` trusts the message's source (or has no TrustedSources); false:
  // refused, counted, a request answered NOT_AVAILABLE when the rate allows.
  bool trusted(const MessageHeader& header, Mailbox& local) noexcept;

  uint8_t system_;
  std::array<Entry, kCapacity> table_{};
  std::atomic<Mailbox*> uplink_{nullptr};
  std::atomic<Mailbox*> large_uplink_{nullptr};
  std::atomic<bool> system_shared_{false};       // relaxed: set before traffic flows
  std::atomic<AccessControl*> access_{nullptr};  // release/acquire: the table is built before
  // Statistics, relaxed: independent counters read by tools.
  std::atomic<uint64_t> delivered_local_{0}, sent_uplink_{0}, not_available_{0}, unroutable_{0}, failed_{0}, denied_{0},
      untrusted_{0};
};

}  // namespace rack::tims
