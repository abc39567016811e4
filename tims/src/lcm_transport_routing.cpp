// LcmTransport: routing. A whole message heard on a network: delivered to a local
// mailbox, answered NOT_AVAILABLE (this host is its system's authority), forwarded
// (routers) or dropped; forged sources refused. Announcements and discover requests:
// taken by Discovery, answered, and passed on by routers.
#include "lcm_transport_impl.h"
#include "lcm_transport_packet.h"

namespace rack::tims {

using namespace lcm_detail;

// Whether a message whose first bytes (its header, any byte order) are `head` is worth
// reassembling here: for a local mailbox, or anything when this host routes, or a
// request this host may have to answer NOT_AVAILABLE.
bool LcmTransport::Impl::wants(const std::byte* head, std::size_t size) {
  if (routes()) return true;
  if (size < sizeof(MessageHeader)) return true;  // let the full check reject it
  MessageHeader h;
  std::memcpy(&h, head, sizeof h);
  if (((h.flags & kFlagHeaderLittleEndian) != 0) != kHostLittleEndian) h.dest = bswap(h.dest);
  const Address dest(h.dest);
  if (router.find(dest) != nullptr) return true;
  if (!h.is_request()) return false;
  return !discovery.known(dest);
}

void LcmTransport::Impl::handle_message(Network& n, std::byte* msg, uint32_t len, int64_t msg_origin, int32_t mseq,
                                        int8_t hops) {
  bump(stats.messages_in);
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
    return n.log.reject("header", [&] {
      return std::string(describe(err)) + (err == MessageError::kLengthMismatch
                                               ? " (from " + h.source().str() + " to " + h.destination().str() + ")"
                                               : std::string());
    });
  }
  const Discovery::Incoming verdict = discovery.incoming(h, msg_origin);
  if (verdict.forged) {
    bump(stats.forged);
    return n.log.warn("forged", [&] {
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
      bump(stats.delivery_failed);
      n.log.warn("delivery", [&] {
        return "TiMS/LCM: message from " + h.source().str() + " to " + h.destination().str() + " (" +
               std::to_string(len) + " bytes) not delivered: " + describe(s);
      });
    }
    return;
  }
  if (verdict.answer_not_available) {
    bump(stats.not_available);
    const MessageHeader reply = make_reply_header(h, msg::kNotAvailable, 0);
    alignas(8) std::byte raw[sizeof reply];
    std::memcpy(raw, &reply, sizeof reply);
    (void)n.publish_message(raw, sizeof raw, origin, 0, 0, next_message_seq());
    return;
  }
  if (forward_message(n, msg, h, len, msg_origin, mseq, hops)) return;
  bump(stats.not_for_us);
}

// Routers: relays a message heard on `in` to the networks where it belongs.
bool LcmTransport::Impl::forward_message(Network& in, const std::byte* msg, const MessageHeader& h, uint32_t len,
                                         int64_t msg_origin, int32_t mseq, int8_t hops) {
  if (!routes()) return false;
  if (hops >= kMaxHops) return false;
  bool any = false;
  for (auto& out : networks) {
    if (out.get() == &in || !should_forward(in.config.scope, out->config.scope, h.destination().system())) continue;
    if (out->publish_message(msg, len, msg_origin, origin, static_cast<int8_t>(hops + 1), mseq, true)) {
      bump(stats.forwarded);
      any = true;
    }
  }
  return any;
}

bool LcmTransport::Impl::should_forward(NetworkScope from, NetworkScope to, uint8_t dest_system) const {
  if (from == to) return false;
  if (dest_system == kToolSystem) return true;
  if (from == NetworkScope::kRobot) return dest_system != discovery.own_system();  // leaves the robot
  return dest_system == discovery.own_system();                                    // enters the robot
}

// An announcement: into the discovery table; routers pass it on, a robot's own hosts
// outwards (to the fleet), other robots' hosts inwards (to the robot): the opposite
// direction of messages.
void LcmTransport::Impl::on_announce(Network& n, const uint8_t* d, std::size_t size) {
  rack_lcm::host_announce a;
  if (!discovery.take_announcement(n.log, d, size, a)) return;
  if (!routes() || a.hops >= kMaxHops) return;
  for (auto& out : networks) {
    if (out.get() == &n || n.config.scope == out->config.scope) continue;
    const bool own = static_cast<uint8_t>(a.system) == discovery.own_system();
    if (own != (n.config.scope == NetworkScope::kRobot)) continue;
    rack_lcm::host_announce f = a;
    f.relay = origin;
    f.hops = static_cast<int8_t>(a.hops + 1);
    std::lock_guard lock(out->publish_mutex);
    if (out->publish_typed_locked(kAnnounceChannel, f) != 0) bump(stats.publish_errors);
  }
}

// A discover request: answered with this host's announcement (at once, or coalesced:
// Discovery::take_discover); routers pass on the requests that were not coalesced.
void LcmTransport::Impl::on_discover(Network& n, const uint8_t* d, std::size_t size) {
  rack_lcm::discover_request r;
  const Discovery::DiscoverAnswer answer = discovery.take_discover(n.index, n.log, d, size, r);
  if (answer.answer_now) publish_announcement(n.index);
  if (!answer.pass_on || !routes() || r.hops >= kMaxHops) return;
  for (auto& out : networks) {
    if (out.get() == &n) continue;
    rack_lcm::discover_request f = r;
    f.relay = origin;
    f.hops = static_cast<int8_t>(r.hops + 1);
    std::lock_guard lock(out->publish_mutex);
    if (out->publish_typed_locked(kDiscoverChannel, f) != 0) bump(stats.publish_errors);
  }
}

}  // namespace rack::tims
