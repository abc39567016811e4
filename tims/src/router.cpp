#include "rack/tims/router.h"

#include <cstring>
#include <stdexcept>

#include "rack/rt/clock.h"
#include "rack/rt/trace.h"
#include "rack/tims/trusted_sources.h"

namespace rack::tims {

void Router::add(Mailbox& mailbox) {
  const uint32_t key = mailbox.address().raw();
  if (key == kEmpty) throw std::invalid_argument("address " + mailbox.address().str() + " is reserved");
  std::size_t i = slot_of(key);
  for (std::size_t n = 0; n < kCapacity; ++n, i = (i + 1) % kCapacity) {
    const uint32_t k = table_[i].key.load(std::memory_order_acquire);
    if (k == key) {
      if (table_[i].mailbox.load(std::memory_order_acquire) != nullptr) {
        throw std::invalid_argument("mailbox " + mailbox.address().str() + " is already registered");
      }
      table_[i].mailbox.store(&mailbox, std::memory_order_release);
      return;
    }
    if (k == kEmpty) {
      table_[i].mailbox.store(&mailbox, std::memory_order_relaxed);
      table_[i].key.store(key, std::memory_order_release);  // publishes the mailbox too
      return;
    }
  }
  throw std::length_error("router table full (" + std::to_string(kCapacity) + " mailboxes)");
}

void Router::remove(Address address) noexcept {
  // The key stays as a tombstone (probe chains stay intact); a later add() of the
  // same address reuses it.
  std::size_t i = slot_of(address.raw());
  for (std::size_t n = 0; n < kCapacity; ++n, i = (i + 1) % kCapacity) {
    const uint32_t k = table_[i].key.load(std::memory_order_acquire);
    if (k == address.raw()) {
      table_[i].mailbox.store(nullptr, std::memory_order_release);
      return;
    }
    if (k == kEmpty) return;
  }
}

void Router::set_uplink(Mailbox* uplink, Mailbox* large_uplink) noexcept {
  large_uplink_.store(large_uplink, std::memory_order_release);
  uplink_.store(uplink, std::memory_order_release);
}

void Router::set_system_shared(bool shared) noexcept { system_shared_.store(shared, std::memory_order_relaxed); }

void Router::set_access(AccessControl* access) noexcept { access_.store(access, std::memory_order_release); }

Mailbox* Router::find(Address address) const noexcept {
  const uint32_t key = address.raw();
  std::size_t i = slot_of(key);
  for (std::size_t n = 0; n < kCapacity; ++n, i = (i + 1) % kCapacity) {
    const uint32_t k = table_[i].key.load(std::memory_order_acquire);
    if (k == key) return table_[i].mailbox.load(std::memory_order_acquire);
    if (k == kEmpty) return nullptr;
  }
  return nullptr;
}

bool Router::is_remote(Address address) const noexcept {
  return address.system() != system_ || address.system() == kToolSystem;
}

namespace {
void bump(std::atomic<uint64_t>& c) noexcept { c.fetch_add(1, std::memory_order_relaxed); }
}  // namespace

SendStatus Router::answer_not_available(const MessageHeader& request) noexcept {
  bump(not_available_);
  const MessageHeader reply = make_reply_header(request, msg::kNotAvailable, 0);
  // A reply never triggers another NOT_AVAILABLE, so this recursion ends here.
  (void)send(reply, std::span<const ConstBuffer>{});
  return SendStatus::kNotAvailable;
}

bool Router::admit(const MessageHeader& header, Mailbox& local, MessageOrigin origin) noexcept {
  AccessControl* access = access_.load(std::memory_order_acquire);
  if (access == nullptr) return true;
  const AccessDecision d = access->check(header, origin);
  if (d.allowed()) return true;
  bump(denied_);
  local.count_denied();
  if (header.is_request() && d.answer) {
    // The ERROR reply says why (wire::ErrorText's layout: a NUL-terminated text). A
    // reply is never a request, so this recursion ends here.
    char text[120];
    access->denial_text(d, text, sizeof text);
    const MessageHeader reply = make_reply_header(header, msg::kError, sizeof text);
    const ConstBuffer part{text, sizeof text};
    (void)send(reply, std::span<const ConstBuffer>(&part, 1));
  }
  return false;
}

bool Router::trusted(const MessageHeader& header, Mailbox& local) noexcept {
  if (header.is_request() && local.replies_only()) {
    bump(untrusted_);
    local.count_refused_request();
    return false;
  }
  TrustedSources* t = local.trusted_sources();
  if (t == nullptr) return true;
  const int64_t now = rt::monotonic_ns();
  const TrustedSources::Verdict v = t->check(header, now);
  if (v == TrustedSources::Verdict::kAccept) return true;
  bump(untrusted_);
  // A request for a data mailbox: RACK answers NOT_AVAILABLE to a request for a
  // mailbox that serves none (a reply never comes back here: it is not a request).
  if (v == TrustedSources::Verdict::kRequest && t->may_answer(now)) (void)answer_not_available(header);
  return false;
}

SendStatus Router::route_unknown(const MessageHeader& header) noexcept {
  if (header.is_request()) return answer_not_available(header);
  bump(unroutable_);
  return SendStatus::kNotAvailable;
}

SendStatus Router::send(const MessageHeader& header, std::initializer_list<ConstBuffer> body) noexcept {
  return send(header, std::span<const ConstBuffer>(body.begin(), body.size()));
}

SendStatus Router::send(const MessageHeader& header, std::span<const ConstBuffer> body) noexcept {
  const Address dest = header.destination();
  // The task timeline's hand-off (before delivery: the send precedes the receive).
  rt::trace::record(rt::trace::Kind::kSend, 0, header.dest, rt::trace::message_aux(header.type, header.seq),
                    header.src);
  if (Mailbox* local = find(dest)) {
    if (!admit(header, *local, MessageOrigin::kLocal)) return SendStatus::kDenied;
    if (!trusted(header, *local)) return SendStatus::kDenied;
    const SendStatus s = local->try_send(header, body);
    bump(delivered(s) ? delivered_local_ : failed_);
    if (DeliveryHook* hook = local->delivery_hook(); hook != nullptr && delivered(s)) [[unlikely]] {
      hook->delivered(*local);  // a stepped executor serves it now (rack/core/stepper.h)
    }
    return s;
  }
  if (is_remote(dest) || system_shared_.load(std::memory_order_relaxed)) {
    if (Mailbox* up = uplink_.load(std::memory_order_acquire)) {
      if (header.length > up->slot_size()) {
        if (Mailbox* large = large_uplink_.load(std::memory_order_acquire)) up = large;
      }
      const SendStatus s = up->try_send(header, body);
      bump(delivered(s) ? sent_uplink_ : failed_);
      return s;
    }
  }
  return route_unknown(header);
}

SendStatus Router::send_bytes(std::span<const std::byte> message) noexcept {
  MessageHeader header;
  std::memcpy(&header, message.data(), sizeof header);
  const ConstBuffer body{message.data() + sizeof header, message.size() - sizeof header};
  return send(header, std::span<const ConstBuffer>(&body, 1));
}

SendStatus Router::deliver_local(std::span<const std::byte> message) noexcept {
  MessageHeader header;
  std::memcpy(&header, message.data(), sizeof header);
  if (Mailbox* local = find(header.destination())) {
    if (!admit(header, *local, MessageOrigin::kNetwork)) return SendStatus::kDenied;
    if (!trusted(header, *local)) return SendStatus::kDenied;
    const SendStatus s = local->try_send_bytes(message);
    bump(delivered(s) ? delivered_local_ : failed_);
    return s;
  }
  if (header.destination().system() == system_ && system_ != kToolSystem &&
      !system_shared_.load(std::memory_order_relaxed)) {
    return route_unknown(header);
  }
  return SendStatus::kNotAvailable;  // someone else's: not ours to answer
}

RouterCounters Router::counters() const noexcept {
  RouterCounters c;
  c.delivered_local = delivered_local_.load(std::memory_order_relaxed);
  c.sent_uplink = sent_uplink_.load(std::memory_order_relaxed);
  c.not_available = not_available_.load(std::memory_order_relaxed);
  c.unroutable = unroutable_.load(std::memory_order_relaxed);
  c.failed = failed_.load(std::memory_order_relaxed);
  c.denied = denied_.load(std::memory_order_relaxed);
  c.untrusted = untrusted_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace rack::tims
