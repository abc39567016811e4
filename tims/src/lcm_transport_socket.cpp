// LcmTransport: the datagrams of a udpm network, read from our own socket (no LCM
// receive thread): looked at first, then read whole, read into a reassembly slot, or
// dropped unread. Receive threads only.
#include "lcm_transport_impl.h"

#include <sys/socket.h>
#include <sys/uio.h>

#include "rack/rt/clock.h"

namespace rack::tims {

using namespace lcm_detail;

// Reads one datagram from our own socket; false when there is none. A datagram
// above kPeekBytes is looked at first (its LCM framing, tims_packet prefix and
// message header): what this host does not need (LCM fragments, other channels, our
// own packets echoed by multicast, chunks of messages for other hosts, duplicates)
// is dropped without copying it out of the kernel, and a chunk of a message being
// reassembled is read straight into its reassembly slot. On a shared network every
// host hears every 4 MB scan; only its receiver pays for more than the peek.
// The peek costs a system call: it is made only while large datagrams come (the one
// before was large), so small ones (RPC) are read in one call as before.
// On a keyed network every datagram is read whole: its MAC covers all of it and is
// checked (authentic) before anything of it is used, so no chunk goes into a
// reassembly slot unverified.
bool LcmTransport::Impl::read_datagram(Network& n) {
  constexpr std::size_t kPeekBytes = 256;
  if (!n.peek_next || n.verifier) {
    const ssize_t got = recv(n.raw_fd, n.datagram.data(), n.datagram.size(), MSG_DONTWAIT | MSG_TRUNC);
    if (got < 0) return false;
    n.peek_next = static_cast<std::size_t>(got) > kPeekBytes;
    if (static_cast<std::size_t>(got) > n.datagram.size()) {
      reject(n, "lcm", [&] { return "datagram of " + std::to_string(got) + " bytes truncated"; });
    } else {
      on_datagram(n, n.datagram.data(), static_cast<std::size_t>(got));
    }
    return true;
  }
  const ssize_t full = recv(n.raw_fd, n.datagram.data(), kPeekBytes, MSG_DONTWAIT | MSG_PEEK | MSG_TRUNC);
  if (full < 0) return false;
  const auto size = static_cast<std::size_t>(full);
  n.peek_next = size > kPeekBytes;
  const auto discard = [&] { (void)recv(n.raw_fd, nullptr, 0, MSG_DONTWAIT); };
  if (size > n.datagram.size()) {
    discard();
    reject(n, "lcm", [&] { return "datagram of " + std::to_string(size) + " bytes truncated"; });
    return true;
  }
  const uint8_t* d = n.datagram.data();
  const auto read_whole = [&] {
    const ssize_t got = recv(n.raw_fd, n.datagram.data(), n.datagram.size(), MSG_DONTWAIT);
    if (got >= 0) on_datagram(n, n.datagram.data(), static_cast<std::size_t>(got));
  };
  if (size <= kPeekBytes || size < 8) {
    read_whole();
    return true;
  }
  const auto magic = static_cast<uint32_t>(get_be(d, 4));
  if (magic == kLcmFragmentMagic) {  // refused, as on_datagram does
    discard();
    refuse_fragment(n, size);
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
      discard();
    }
    return true;
  }
  const std::size_t at = 8 + len + 1;  // the tims_packet
  const ChunkPlan plan = plan_chunk(n, d + at, size - at, kTimsChannel);
  if (plan.kind == ChunkPlan::kSingle) {
    read_whole_packet(n, at, size);
    return true;
  }
  if (plan.kind != ChunkPlan::kSlot) {
    discard();
    return true;
  }
  // LCM framing and prefix into the datagram buffer, the chunk into its slot.
  iovec iov[2] = {{n.datagram.data(), at + kPacketPrefix}, {plan.slot->data.data() + plan.offset, plan.size}};
  msghdr mh{};
  mh.msg_iov = iov;
  mh.msg_iovlen = 2;
  const ssize_t got = recvmsg(n.raw_fd, &mh, MSG_DONTWAIT);
  if (got != static_cast<ssize_t>(size)) {
    unplan_chunk(*plan.slot, plan.offset);  // cannot happen (one reader per socket)
    return got >= 0;
  }
  finish_chunk(n, *plan.slot);
  return true;
}

// A single-chunk message whose prefix was planned already: read it, take it.
void LcmTransport::Impl::read_whole_packet(Network& n, std::size_t at, std::size_t size) {
  const ssize_t got = recv(n.raw_fd, n.datagram.data(), n.datagram.size(), MSG_DONTWAIT);
  if (got != static_cast<ssize_t>(size)) return;
  const uint8_t* d = n.datagram.data() + at;
  take_stream(n, reinterpret_cast<const std::byte*>(d + kPacketPrefix), false,
              static_cast<uint32_t>(size - at - kPacketPrefix), static_cast<uint32_t>(get_i32(d + kOffTotal)),
              static_cast<int8_t>(d[kOffEncoding]), get_i64(d + kOffOrigin), get_i32(d + kOffMessageSeq),
              static_cast<int8_t>(d[kOffHops]));
}

// One datagram from our own socket: LCM's framing (lcm_wire.h), then our channels.
// LCM fragments are refused and counted: ours never are (chunks stay below LCM's
// fragmentation size), and LCM 1.3's own reassembly of them trusts its input.
void LcmTransport::Impl::on_datagram(Network& n, const uint8_t* d, std::size_t size) {
  const wire_lcm::LcmDatagram g = wire_lcm::parse_datagram(d, size);
  if (g.kind == wire_lcm::LcmDatagram::kFragment) return refuse_fragment(n, size);
  if (g.kind != wire_lcm::LcmDatagram::kMessage) {
    return reject(n, "lcm", [&] { return std::to_string(size) + "-byte datagram: " + g.why; });
  }
  const std::string_view channel = g.channel;
  std::size_t payload_size = g.payload_size;
  // Other channels on the same network (GDOS, tools): not ours.
  if (channel != kTimsChannel && channel != kAnnounceChannel && channel != kDiscoverChannel) return;
  if (!authentic(n, channel, g.payload, payload_size)) return;
  if (channel == kTimsChannel) return on_packet(n, g.payload, payload_size, kTimsChannel);
  if (channel == kAnnounceChannel) return on_announce(n, g.payload, payload_size, kAnnounceChannel);
  on_discover(n, g.payload, payload_size, kDiscoverChannel);
}

void LcmTransport::Impl::refuse_fragment(Network& n, std::size_t size) {
  bump(lcm_fragments);
  warn("fragment " + n.config.name, [&] {
    return "TiMS/LCM: refused an LCM fragment (" + std::to_string(size) + " bytes) on network '" + n.config.name +
           "' (" + n.config.url + "): RACK-RT never sends messages above LCM's 64 KB fragmentation size";
  });
}

}  // namespace rack::tims
