// One network of the transport: its parts (LcmSocket, LinkAuth, ChunkPublisher,
// ChunkReassembler) wired together, and its receive path: datagrams looked at, read
// whole, read into a reassembly slot or dropped unread; payloads authenticated and
// handed on by channel (lcm_transport_impl.h).
#include <sys/types.h>

#include <cstring>

#include "lcm_transport_impl.h"
#include "lcm_transport_packet.h"

namespace rack::tims {

using namespace lcm_detail;

namespace {

ChunkLimits chunk_limits(const LcmTransportConfig& c) {
  ChunkLimits l;
  l.max_message_bytes = c.max_message_bytes;
  l.slots = c.reassembly_slots;
  l.timeout_ns = c.reassembly_timeout_ns;
  return l;
}

}  // namespace

LcmTransport::Impl::Network::Network(Impl& transport, std::size_t net_index, const NetworkConfig& net_config)
    : impl(transport),
      index(net_index),
      config(net_config),
      log(transport.stats, transport.warn, config.name, config.url),
      socket(config, *this),
      auth(config, transport.origin, transport.config.replay_window_ns),
      publisher(config, transport.config.max_message_bytes, auth.trailer_bytes(), log),
      reassembler(transport.origin, chunk_limits(transport.config), log, *this) {}

bool LcmTransport::Impl::Network::publish_message(const std::byte* msg, uint32_t len, int64_t msg_origin, int64_t relay,
                                                  int8_t hops, int32_t seq, bool writable) {
  std::lock_guard lock(publish_mutex);
  return publisher.publish(msg, len, msg_origin, relay, hops, seq, writable, *this);
}

int LcmTransport::Impl::Network::send_raw_locked(const char* channel, uint8_t* buf, std::size_t len) {
  auth.sign(channel, buf, len);
  return socket.publish(channel, buf, len);
}

int LcmTransport::Impl::Network::send_packet(uint8_t* buf, std::size_t len) {
  return send_raw_locked(kTimsChannel, buf, len);
}

bool LcmTransport::Impl::Network::wants(const std::byte* head, std::size_t size) { return impl.wants(head, size); }

void LcmTransport::Impl::Network::take_message(std::byte* msg, uint32_t len, int64_t msg_origin, int32_t msg_seq,
                                               int8_t hops) {
  impl.handle_message(*this, msg, len, msg_origin, msg_seq, hops);
}

// Reads one datagram from our own socket; false when there is none. A datagram
// above LcmSocket::kPeekBytes is looked at first (its LCM framing, tims_packet prefix
// and message header): what this host does not need (LCM fragments, other channels,
// our own packets echoed by multicast, chunks of messages for other hosts, duplicates)
// is dropped without copying it out of the kernel, and a chunk of a message being
// reassembled is read straight into its reassembly slot. On a shared network every
// host hears every 4 MB scan; only its receiver pays for more than the peek.
// The peek costs a system call: it is made only while large datagrams come (the one
// before was large), so small ones (RPC) are read in one call as before.
// On a keyed network every datagram is read whole: its MAC covers all of it and is
// checked (LinkAuth::accept) before anything of it is used, so no chunk goes into a
// reassembly slot unverified.
bool LcmTransport::Impl::Network::read_datagram() {
  if (!socket.last_was_large() || auth.keyed()) {
    const ssize_t got = socket.read();
    if (got < 0) return false;
    if (static_cast<std::size_t>(got) > socket.capacity()) {
      log.reject("lcm", [&] { return "datagram of " + std::to_string(got) + " bytes truncated"; });
    } else {
      on_datagram(socket.buffer(), static_cast<std::size_t>(got));
    }
    return true;
  }
  const ssize_t full = socket.peek();
  if (full < 0) return false;
  const auto size = static_cast<std::size_t>(full);
  if (size > socket.capacity()) {
    socket.discard();
    log.reject("lcm", [&] { return "datagram of " + std::to_string(size) + " bytes truncated"; });
    return true;
  }
  const uint8_t* d = socket.buffer();
  const auto read_whole = [&] {
    const ssize_t got = socket.read();
    if (got >= 0) on_datagram(socket.buffer(), static_cast<std::size_t>(got));
  };
  if (size <= LcmSocket::kPeekBytes || size < 8) {
    read_whole();
    return true;
  }
  const auto magic = static_cast<uint32_t>(get_be(d, 4));
  if (magic == kLcmFragmentMagic) {  // refused, as on_datagram does
    socket.discard();
    refuse_fragment(size);
    return true;
  }
  const auto* name = reinterpret_cast<const char*>(d + 8);
  const std::size_t len = strnlen(name, 64);
  if (magic != kLcmShortMagic || len == 64) {  // on_datagram says what is wrong
    read_whole();
    return true;
  }
  const std::string_view channel(name, len);
  if (channel != kTimsChannel) {
    // Large announcements are read whole; other channels (GDOS, tools) are not ours.
    if (channel == kAnnounceChannel || channel == kDiscoverChannel) {
      read_whole();
    } else {
      socket.discard();
    }
    return true;
  }
  const std::size_t at = 8 + len + 1;  // the tims_packet
  const ChunkReassembler::Plan plan = reassembler.plan(d + at, size - at, kTimsChannel);
  if (plan.kind == ChunkReassembler::Plan::kSingle) {
    // A single-chunk message whose prefix was planned already: read it, take it.
    const ssize_t got = socket.read();
    if (got == static_cast<ssize_t>(size)) reassembler.take_single(socket.buffer() + at, size - at);
    return true;
  }
  if (plan.kind != ChunkReassembler::Plan::kSlot) {
    socket.discard();
    return true;
  }
  // LCM framing and prefix into the datagram buffer, the chunk into its slot.
  const ssize_t got = socket.read_split(at + kPacketPrefix, plan.into, plan.size);
  if (got != static_cast<ssize_t>(size)) {
    reassembler.unplan(plan);  // cannot happen (one reader per socket)
    return got >= 0;
  }
  reassembler.finish(plan);
  return true;
}

// One datagram from our own socket: LCM's framing (lcm_wire.h), then our channels.
// LCM fragments are refused and counted: ours never are (chunks stay below LCM's
// fragmentation size), and LCM 1.3's own reassembly of them trusts its input.
void LcmTransport::Impl::Network::on_datagram(const uint8_t* d, std::size_t size) {
  const wire_lcm::LcmDatagram g = wire_lcm::parse_datagram(d, size);
  if (g.kind == wire_lcm::LcmDatagram::kFragment) return refuse_fragment(size);
  if (g.kind != wire_lcm::LcmDatagram::kMessage) {
    return log.reject("lcm", [&] { return std::to_string(size) + "-byte datagram: " + g.why; });
  }
  on_payload(g.channel, g.payload, g.payload_size);
}

// A payload on a channel of this network (from our own socket, or from LCM's
// subscriptions): other channels (GDOS, tools) are not ours; ours are authenticated,
// then handed to the reassembler or to discovery.
void LcmTransport::Impl::Network::on_payload(std::string_view channel, const uint8_t* d, std::size_t size) {
  if (channel != kTimsChannel && channel != kAnnounceChannel && channel != kDiscoverChannel) return;
  if (!auth.accept(channel, d, size, log)) return;
  if (channel == kTimsChannel) return reassembler.on_packet(d, size, kTimsChannel);
  if (channel == kAnnounceChannel) return impl.on_announce(*this, d, size);
  impl.on_discover(*this, d, size);
}

void LcmTransport::Impl::Network::refuse_fragment(std::size_t size) {
  bump(impl.stats.lcm_fragments);
  log.warn("fragment " + config.name, [&] {
    return "TiMS/LCM: refused an LCM fragment (" + std::to_string(size) + " bytes) on network '" + config.name + "' (" +
           config.url + "): RACK-RT never sends messages above LCM's 64 KB fragmentation size";
  });
}

}  // namespace rack::tims
