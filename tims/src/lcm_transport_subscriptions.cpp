// The data flows that cross to other hosts, and how a lost host ends them
// (lcm_transport_subscriptions.h).
#include "lcm_transport_subscriptions.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <set>

#include "rack/rt/clock.h"

namespace rack::tims {

using lcm_detail::bump;

// Body layouts: rack::wire::ContDataRequest (int64 period, uint32 mailbox) and
// StopContDataRequest (uint32 mailbox), native.
void RemoteSubscriptions::track(const MessageHeader& h, std::span<const std::byte> body) {
  if (h.type == msg::kGetContData && body.size() >= 12) {
    uint32_t mailbox = 0;
    std::memcpy(&mailbox, body.data() + 8, 4);
    const uint32_t producer = h.destination().component().raw();
    forget(producer, mailbox);
    if (subscriptions_.size() < kMaxTracked) subscriptions_.push_back({producer, mailbox, h.priority});
  } else if (h.type == msg::kStopContData && body.size() >= 4) {
    uint32_t mailbox = 0;
    std::memcpy(&mailbox, body.data(), 4);
    forget(h.destination().component().raw(), mailbox);
  }
  if (h.type == msg::kData && router_.find(h.source()) != nullptr) {
    const uint64_t key = (uint64_t{h.source().component().raw()} << 32) | h.dest;
    if (streams_.size() < kMaxTracked || streams_.count(key) != 0) streams_[key] = rt::monotonic_ns();
  }
}

void RemoteSubscriptions::forget(uint32_t producer, uint32_t listener) {
  subscriptions_.erase(
      std::remove_if(subscriptions_.begin(), subscriptions_.end(),
                     [&](const Subscription& s) { return s.producer == producer && s.listener == listener; }),
      subscriptions_.end());
}

void RemoteSubscriptions::end(const HostInfo& lost, const std::string& why) {
  std::set<uint32_t> gone;
  gone.insert(lost.executor.component().raw());
  for (const auto& c : lost.components) gone.insert(c.address.component().raw());
  char text[120] = {};
  std::snprintf(text, sizeof text, "host '%s' lost: %s", lost.host.c_str(), why.c_str());
  auto it = subscriptions_.begin();
  while (it != subscriptions_.end()) {
    if (gone.count(it->producer) == 0) {
      ++it;
      continue;
    }
    const MessageHeader h = make_header(Address(it->listener), Address(it->producer), msg::kError, it->priority, 0,
                                        sizeof text);
    const ConstBuffer part{text, sizeof text};
    (void)router_.send(h, std::span<const ConstBuffer>(&part, 1));
    bump(stats_.subscriptions_failed);
    it = subscriptions_.erase(it);
  }
  for (auto st = streams_.begin(); st != streams_.end();) {
    const auto listener = static_cast<uint32_t>(st->first);
    if (gone.count(Address(listener).component().raw()) == 0) {
      ++st;
      continue;
    }
    const Address producer(static_cast<uint32_t>(st->first >> 32));
    const uint32_t body[2] = {listener, 0};  // rack::wire::StopContDataRequest
    const MessageHeader h = make_header(producer, control_, msg::kStopContData, 0, 0, sizeof body);
    const ConstBuffer part{body, sizeof body};
    (void)router_.send(h, std::span<const ConstBuffer>(&part, 1));
    bump(stats_.streams_stopped);
    st = streams_.erase(st);
  }
}

}  // namespace rack::tims
