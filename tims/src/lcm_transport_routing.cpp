// LcmTransport: a whole message heard on a network: delivered to a local mailbox,
// answered NOT_AVAILABLE (this host is its system's authority), forwarded (routers)
// or dropped; forged sources refused.
#include "lcm_transport_impl.h"

namespace rack::tims {

using namespace lcm_detail;

// Whether a message whose first bytes (its header, any byte order) are `head` is worth
// reassembling here: for a local mailbox, or anything when this host routes, or a
// request this host may have to answer NOT_AVAILABLE.
bool LcmTransport::Impl::wants(const std::byte* head, std::size_t size) {
  if (role() == NodeRole::kSystemRouter || role() == NodeRole::kTopRouter) return true;
  if (size < sizeof(MessageHeader)) return true;  // let the full check reject it
  MessageHeader h;
  std::memcpy(&h, head, sizeof h);
  if (((h.flags & kFlagHeaderLittleEndian) != 0) != kHostLittleEndian) h.dest = bswap(h.dest);
  const Address dest(h.dest);
  if (router.find(dest) != nullptr) return true;
  if (!h.is_request()) return false;
  std::lock_guard lock(table_mutex);
  return !known_locked(dest);
}

void LcmTransport::Impl::handle_message(Network& n, std::byte* msg, uint32_t len, int64_t msg_origin, int32_t mseq,
                                        int8_t hops) {
  bump(messages_in);
  const std::span<const std::byte> bytes(msg, len);
  MessageHeader h;
  const MessageError err = decode_header(bytes, h);
  if (err != MessageError::kOk) {
    if (err == MessageError::kLengthMismatch && h.is_request() && router.find(h.destination()) != nullptr &&
        router.find(h.source()) == nullptr) {
      // We know who sent it: a request to one of our mailboxes gets an ERROR reply.
      const MessageHeader reply = make_reply_header(h, msg::kError, 0);
      (void)router.send(reply, std::span<const ConstBuffer>{});
    }
    return reject(n, "header", [&] {
      return std::string(describe(err)) + (err == MessageError::kLengthMismatch
                                               ? " (from " + h.source().str() + " to " + h.destination().str() + ")"
                                               : std::string());
    });
  }
  // Forged source: an address of ours, or of a component another host announced.
  bool forged_source = router.find(h.source()) != nullptr;
  bool dest_known = false;
  bool authority = false;
  {
    std::lock_guard lock(table_mutex);
    if (!forged_source && h.source().system() != kToolSystem) {
      const auto it = owners.find(h.source().component().raw());
      forged_source = it != owners.end() && it->second != msg_origin;
    }
    dest_known = known_locked(h.destination());
    if (!dest_known && h.is_request()) authority = authoritative_locked(h.destination().system());
    if (h.type == msg::kError) forget_subscription_locked(h.source().component().raw(), h.dest);
  }
  if (forged_source) {
    bump(forged);
    return warn("forged", [&] {
      return "TiMS/LCM: dropped a message with a forged source on network '" + n.config.name +
             "': " + h.source().str() + " -> " + h.destination().str() + " from origin " + origin_text(msg_origin) +
             ", which does not own " + h.source().str();
    });
  }
  std::memcpy(msg, &h, sizeof h);  // header in host byte order
  if (router.find(h.destination()) != nullptr) {
    const SendStatus s = router.deliver_local(bytes);
    // kDenied: access control refused it, counted and logged there (per rule).
    if (!delivered(s) && s != SendStatus::kDenied) {
      bump(delivery_failed);
      warn("delivery", [&] {
        return "TiMS/LCM: message from " + h.source().str() + " to " + h.destination().str() + " (" +
               std::to_string(len) + " bytes) not delivered: " + describe(s);
      });
    }
    return;
  }
  if (authority) {
    bump(not_available);
    const MessageHeader reply = make_reply_header(h, msg::kNotAvailable, 0);
    alignas(8) std::byte raw[sizeof reply];
    std::memcpy(raw, &reply, sizeof reply);
    (void)publish_message(n, raw, sizeof raw, origin, 0, 0, next_message_seq());
    return;
  }
  if (forward_message(n, msg, h, len, msg_origin, mseq, hops)) return;
  bump(not_for_us);
}

// Routers: relays a message heard on `in` to the networks where it belongs.
bool LcmTransport::Impl::forward_message(Network& in, const std::byte* msg, const MessageHeader& h, uint32_t len,
                                         int64_t msg_origin, int32_t mseq, int8_t hops) {
  if (role() != NodeRole::kSystemRouter && role() != NodeRole::kTopRouter) return false;
  if (hops >= kMaxHops) return false;
  bool any = false;
  for (auto& out : networks) {
    if (out.get() == &in || !should_forward(in.config.scope, out->config.scope, h.destination().system())) continue;
    if (publish_message(*out, msg, len, msg_origin, origin, static_cast<int8_t>(hops + 1), mseq, true)) {
      bump(forwarded);
      any = true;
    }
  }
  return any;
}

bool LcmTransport::Impl::should_forward(NetworkScope from, NetworkScope to, uint8_t dest_system) const {
  if (from == to) return false;
  if (dest_system == kToolSystem) return true;
  if (from == NetworkScope::kRobot) return dest_system != own_system;  // leaves the robot
  return dest_system == own_system;                                    // enters the robot
}

}  // namespace rack::tims
