#include "rack/tims/lcm_transport.h"
#include "rack/tims/lcm_url.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <sys/random.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "rack/rt/clock.h"
#include "rack/rt/thread.h"
#include "rack/tims/link_auth.h"
#include "lcm_receive.h"
#include "lcm_wire.h"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/host_announce.hpp"
#include "rack_lcm/tims_packet.hpp"

namespace rack::tims {

const char* describe(NetworkScope s) noexcept { return s == NetworkScope::kRobot ? "robot" : "fleet"; }
const char* describe(Compression c) noexcept { return c == Compression::kZstd ? "zstd" : "none"; }
const char* describe(NodeRole r) noexcept {
  switch (r) {
    case NodeRole::kExecutor: return "executor";
    case NodeRole::kSystemRouter: return "system_router";
    case NodeRole::kTopRouter: return "top_router";
    case NodeRole::kTool: return "tool";
  }
  return "unknown";
}

namespace {

constexpr const char* kTimsChannel = "TIMS";
constexpr const char* kAnnounceChannel = "TIMS_ANNOUNCE";
constexpr const char* kDiscoverChannel = "TIMS_DISCOVER";

// Wire layout of tims_packet (LCM encodes big-endian): 8-byte fingerprint, then the
// fields in declaration order. Offsets of each field:
constexpr std::size_t kOffOrigin = 8;
constexpr std::size_t kOffRelay = 16;
constexpr std::size_t kOffPacketSeq = 24;
constexpr std::size_t kOffMessageSeq = 28;
constexpr std::size_t kOffTotal = 32;
constexpr std::size_t kOffEncoded = 36;
constexpr std::size_t kOffOffset = 40;
constexpr std::size_t kOffEncoding = 44;
constexpr std::size_t kOffHops = 45;
constexpr std::size_t kOffSize = 46;
constexpr std::size_t kPacketPrefix = 50;
// Bytes of a message per chunk: every LCM datagram stays below LCM's own
// fragmentation limit (about 64 KB), so LCM never reassembles our traffic and a
// receiver knows which message a lost chunk belongs to. Every chunk but the last of a
// message is exactly this long (receivers check it).
constexpr uint32_t kChunk = 60000;
// Routers passed before a packet is dropped (a mis-wired fleet must not loop forever).
constexpr int8_t kMaxHops = 4;

void put_be(uint8_t* p, uint64_t v, int bytes) {
  if (bytes == 8) {
    v = __builtin_bswap64(v);
    std::memcpy(p, &v, 8);
  } else {
    auto w = __builtin_bswap32(static_cast<uint32_t>(v));
    std::memcpy(p, &w, 4);
  }
}
uint64_t get_be(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}
int64_t get_i64(const uint8_t* p) { return static_cast<int64_t>(get_be(p, 8)); }
int32_t get_i32(const uint8_t* p) { return static_cast<int32_t>(static_cast<uint32_t>(get_be(p, 4))); }

int64_t random_origin() {
  int64_t v = 0;
  while (v == 0) {
    if (getrandom(&v, sizeof v, 0) != static_cast<ssize_t>(sizeof v)) {
      v = rt::monotonic_ns() ^ (static_cast<int64_t>(getpid()) << 32);
    }
  }
  return v;
}

using lcm_rx::RateLimitedWarn;

void bump(std::atomic<uint64_t>& c, uint64_t n = 1) { c.fetch_add(n, std::memory_order_relaxed); }

using wire_lcm::kLcmFragmentMagic;
using wire_lcm::kLcmShortMagic;
// Hosts kept in the discovery table at once: a flood of announcements with made-up
// origins is refused (counted: hosts_refused) instead of growing the table (and the
// work of every announcement) without bound. Far above a fleet's size.
constexpr std::size_t kMaxHosts = 256;

std::string origin_text(int64_t origin) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(origin));
  return buf;
}

}  // namespace

struct LcmTransport::Impl {
  struct Network;

  // A large message being received, in a preallocated buffer.
  struct Reassembly {
    bool used = false;
    int64_t origin = 0;
    int32_t message_seq = 0;
    uint32_t total = 0;
    uint32_t encoded = 0;
    int8_t encoding = 0;
    int8_t hops = 0;
    uint32_t chunks = 0;
    uint32_t received = 0;
    int64_t started_ns = 0;
    std::vector<std::byte> data;
    std::vector<uint8_t> have;  // one flag per chunk
  };

  struct Network {
    Impl* impl = nullptr;
    std::size_t index = 0;
    NetworkConfig config;
    std::unique_ptr<lcm::LCM> lcm;
    std::thread receiver;
    // Publishing (any non-RT thread of this transport): buffers under the mutex.
    std::mutex publish_mutex;
    uint32_t packet_seq = 0;
    std::vector<uint8_t> packet;  // prefix + one chunk
    std::vector<std::byte> compressed;
    ZSTD_CCtx* cctx = nullptr;
    // Receiving (this network's receive thread only).
    std::vector<Reassembly> slots;
    // Large messages for someone else, recognised by their first chunk: their other
    // chunks are dropped at once instead of reassembled (on a shared network every
    // host hears every 4 MB scan). A small ring of (origin, message number).
    std::array<std::pair<int64_t, int32_t>, 16> skipped{};
    std::size_t next_skipped = 0;
    std::vector<std::byte> message;  // a whole message in host byte order, for delivery
    ZSTD_DCtx* dctx = nullptr;
    std::unordered_map<int64_t, uint32_t> last_packet_seq;  // per publisher
    // Our own socket on a udpm network: the receive thread reads datagrams itself
    // instead of through LCM's receive thread and notify pipe (two thread hand-offs
    // less per message; LCM 1.3 has no other way). -1: receive through LCM.
    int raw_fd = -1;
    std::vector<uint8_t> datagram;
    bool peek_next = false;  // look at the next datagram's head first (read_datagram)
    // Authenticated link (key_file): the keys, the signer (under publish_mutex) and
    // the verifier (receive thread). Null on a network without a key.
    std::unique_ptr<KeyRing> keys;
    std::unique_ptr<LinkSigner> signer;
    std::unique_ptr<LinkVerifier> verifier;
    std::vector<uint8_t> scratch;  // encoded typed messages + trailer (under publish_mutex)
    // Discover answers (under Impl::announce_mutex): when this host last announced on
    // this network, and whether a coalesced request waits for its answer.
    int64_t last_announce_ns = INT64_MIN / 2;
    bool answer_pending = false;

    void on_packet(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
      std::size_t size = rbuf->data_size;
      const auto* d = static_cast<const uint8_t*>(rbuf->data);
      if (impl->authentic(*this, channel, d, size)) impl->on_packet(*this, d, size, channel);
    }
    void on_announce(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
      std::size_t size = rbuf->data_size;
      const auto* d = static_cast<const uint8_t*>(rbuf->data);
      if (impl->authentic(*this, channel, d, size)) impl->on_announce(*this, d, size, channel);
    }
    void on_discover(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
      std::size_t size = rbuf->data_size;
      const auto* d = static_cast<const uint8_t*>(rbuf->data);
      if (impl->authentic(*this, channel, d, size)) impl->on_discover(*this, d, size, channel);
    }
  };

  struct HostEntry {
    HostInfo info;
    int64_t first_seen_ns = 0;  // when its origin was first heard (its warm-up began)
  };
  struct Subscription {
    uint32_t producer = 0;  // component address of the remote producer
    uint32_t listener = 0;  // local mailbox that receives the samples
    uint8_t priority = 0;
  };

  Impl(Router& r, LcmTransportConfig c)
      : router(r),
        config(std::move(c)),
        origin(random_origin()),
        uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFF), config.uplink_slots, config.uplink_slot_size),
        large_uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFE), std::max<uint32_t>(config.large_slots, 1),
                     std::max(config.max_message_bytes, config.uplink_slot_size)),
        control(kTransportControlAddress, 16, 512),
        warn(config.warn ? config.warn : [](const std::string& s) { std::cerr << s << std::endl; }) {
    if (config.networks.empty()) {
      NetworkConfig n;
      n.url = config.url;
      config.networks.push_back(n);
    }
    own_system = router.system();
  }
  ~Impl() {
    for (auto& n : networks) {
      if (n->raw_fd >= 0) close(n->raw_fd);
      if (n->cctx != nullptr) ZSTD_freeCCtx(n->cctx);
      if (n->dctx != nullptr) ZSTD_freeDCtx(n->dctx);
    }
  }

  Router& router;
  LcmTransportConfig config;
  const int64_t origin;
  Mailbox uplink;
  Mailbox large_uplink;
  Mailbox control;  // replies to the transport's own requests (STOP_CONT_DATA), drained
  RateLimitedWarn warn;
  std::vector<std::unique_ptr<Network>> networks;
  std::thread sender, large_sender, maintenance;
  // wait_uplink(): the sender threads wake a waiter only when the uplinks have drained
  // to its threshold (one wake-up per batch, not per message).
  std::mutex drain_mutex;
  std::condition_variable drained;
  std::atomic<int64_t> drain_threshold{-1};  // -1: nobody waits
  std::atomic<bool> running{false};
  int64_t started_ns = 0;
  std::atomic<int32_t> message_seq{0};

  // Discovery table and subscriptions (non-RT threads only).
  mutable std::mutex table_mutex;
  std::map<int64_t, HostEntry> hosts;            // by origin
  std::unordered_map<uint32_t, int64_t> owners;  // component address -> origin
  std::vector<Subscription> subscriptions;
  // Streams that leave this host: (local producer component << 32 | remote listener
  // mailbox). When the listener's host is lost, the producer is told to stop
  // (STOP_CONT_DATA), or it would stream into the void for good.
  std::unordered_map<uint64_t, int64_t> streams;
  std::set<int64_t> retired;  // origins of hosts taken for restarted (bounded)
  bool have_own_id = false;
  uint8_t own_system = 0;
  uint8_t own_host_id = 0;

  std::mutex announce_mutex;
  bool have_announcement = false;
  rack_lcm::host_announce announcement;

  std::atomic<uint64_t> packets_in{0}, packets_out{0}, messages_in{0}, messages_out{0}, malformed{0}, forged{0},
      not_for_us{0}, forwarded{0}, not_available{0}, sequence_gaps{0}, lost_messages{0}, publish_errors{0},
      delivery_failed{0}, hosts_expired{0}, subscriptions_failed{0}, streams_stopped{0}, compressed_out{0},
      bytes_out{0}, wire_bytes_out{0}, auth_failed{0}, replayed{0}, malformed_lcm{0}, malformed_packet{0},
      malformed_announce{0}, malformed_discover{0}, lcm_fragments{0}, hosts_refused{0}, discovers_answered{0},
      discovers_suppressed{0};

  // ------------------------------------------------------------------ set-up
  void join() {
    for (std::size_t i = 0; i < config.networks.size(); ++i) {
      auto n = std::make_unique<Network>();
      n->impl = this;
      n->index = i;
      n->config = config.networks[i];
      if (const LcmUrlResult u = parse_lcm_url(n->config.url); !u.ok()) {
        throw std::runtime_error("cannot join the LCM network '" + n->config.name + "': " + u.error);
      }
      n->lcm = std::make_unique<lcm::LCM>(n->config.url);
      if (!n->lcm->good()) {
        throw std::runtime_error("cannot join the LCM network '" + n->config.url +
                                 "' (a network namespace needs 'ip link set lo up' and a multicast "
                                 "route: ip route add 224.0.0.0/4 dev IFACE)");
      }
      if (!n->config.key_file.empty()) {
        try {
          n->keys = std::make_unique<KeyRing>(n->config.key_file);
        } catch (const std::exception& e) {
          throw std::runtime_error("network '" + n->config.name + "': " + e.what());
        }
        n->signer = std::make_unique<LinkSigner>(*n->keys, origin);
        n->verifier = std::make_unique<LinkVerifier>(*n->keys, config.replay_window_ns);
        n->scratch.reserve(4096);
      }
      n->packet.assign(kPacketPrefix + kChunk + kAuthTrailerBytes, 0);
      put_be(n->packet.data(), static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
      if (n->config.compression == Compression::kZstd) {
        n->compressed.resize(ZSTD_compressBound(config.max_message_bytes));
        n->cctx = ZSTD_createCCtx();
      }
      n->dctx = ZSTD_createDCtx();
      n->message.resize(config.max_message_bytes);
      n->slots.resize(std::max<uint32_t>(config.reassembly_slots, 1));
      const uint32_t max_chunks = (config.max_message_bytes + kChunk - 1) / kChunk + 1;
      // Compressed streams can exceed the message a little (incompressible data).
      const std::size_t max_encoded = ZSTD_compressBound(config.max_message_bytes);
      for (auto& s : n->slots) {
        s.data.resize(max_encoded);
        s.have.resize(max_chunks + 1);
      }
      if (const auto u = lcm_rx::parse_udpm(n->config.url)) {
        // LCM then only publishes: it opens its receive socket and thread on the first
        // subscription, and there is none.
        n->raw_fd = lcm_rx::open_udpm_socket(n->config.url, *u);
        n->datagram.resize(65536);
      } else {
        auto* sub = n->lcm->subscribe(kTimsChannel, &Network::on_packet, n.get());
        sub->setQueueCapacity(1024);  // LCM's default (~30) silently drops bursts
        n->lcm->subscribe(kAnnounceChannel, &Network::on_announce, n.get())->setQueueCapacity(256);
        n->lcm->subscribe(kDiscoverChannel, &Network::on_discover, n.get())->setQueueCapacity(64);
      }
      networks.push_back(std::move(n));
    }
  }

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
  bool read_datagram(Network& n) {
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
  void read_whole_packet(Network& n, std::size_t at, std::size_t size) {
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
  void on_datagram(Network& n, const uint8_t* d, std::size_t size) {
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

  void refuse_fragment(Network& n, std::size_t size) {
    bump(lcm_fragments);
    warn("fragment " + n.config.name, [&] {
      return "TiMS/LCM: refused an LCM fragment (" + std::to_string(size) + " bytes) on network '" + n.config.name +
             "' (" + n.config.url + "): RACK-RT never sends messages above LCM's 64 KB fragmentation size";
    });
  }

  // ------------------------------------------------------------------ authentication
  // A payload on one of our channels: on a keyed network, verifies and strips its
  // trailer (false: dropped, counted, logged); elsewhere, passes it on. Receive threads.
  bool authentic(Network& n, std::string_view channel, const uint8_t* d, std::size_t& size) {
    if (!n.verifier) {
      // A signed packet on a network without a key here: this host lacks the key
      // (refused, with a message that says so, instead of half-working on what LCM's
      // decoders would accept). Recognised by a trailer right after the packet's end.
      const auto signed_after = [&](std::size_t end) {
        return looks_signed(d, size) && end + kAuthTrailerBytes == size;
      };
      bool is_signed = false;
      if (channel == kTimsChannel) {
        is_signed = size >= kPacketPrefix + kAuthTrailerBytes && signed_after(get_be(d + kOffSize, 4) + kPacketPrefix);
      } else if (channel == kAnnounceChannel) {
        rack_lcm::host_announce a;
        std::string why;
        const int used = looks_signed(d, size) ? wire_lcm::decode(d, size, a, why) : -1;
        is_signed = used > 0 && signed_after(static_cast<std::size_t>(used));
      } else if (channel == kDiscoverChannel) {
        rack_lcm::discover_request r;
        std::string why;
        const int used = looks_signed(d, size) ? wire_lcm::decode(d, size, r, why) : -1;
        is_signed = used > 0 && signed_after(static_cast<std::size_t>(used));
      }
      if (is_signed) {
        bump(malformed);
        bump(channel == kAnnounceChannel   ? malformed_announce
             : channel == kDiscoverChannel ? malformed_discover
                                           : malformed_packet);
        warn("unkeyed " + n.config.name, [&] {
          return "TiMS/LCM: dropped a signed packet on network '" + n.config.name + "' (" + n.config.url +
                 "), which has no key_file here: give this host the network's key file";
        });
        return false;
      }
      return true;
    }
    const AuthResult r = n.verifier->verify(channel, d, size, rt::host_time_ns(), rt::monotonic_ns());
    if (r == AuthResult::kOk) {
      size -= kAuthTrailerBytes;
      return true;
    }
    const bool replay = is_replay(r);
    bump(replay ? replayed : auth_failed);
    const int64_t from = n.verifier->last_sender();
    warn((replay ? "replayed " : "auth ") + n.config.name, [&] {
      return "TiMS/LCM: dropped a packet on network '" + n.config.name + "' (" + n.config.url + ", key file " +
             n.keys->path() + ") channel " + std::string(channel) +
             (from != 0 ? " from origin " + origin_text(from) : "") + ": " + describe(r);
    });
    return false;
  }

  // Publishes raw bytes on `n`, signed on a keyed network: `buf` must have
  // kAuthTrailerBytes of room after `len`. Caller holds n.publish_mutex.
  int publish_raw(Network& n, const char* channel, uint8_t* buf, std::size_t len) {
    if (n.signer) {
      n.signer->sign(channel, buf, len, buf + len, rt::host_time_ns());
      len += kAuthTrailerBytes;
    }
    return n.lcm->publish(channel, buf, static_cast<unsigned>(len));
  }

  // Publishes an lcm-gen message on `n`, signed on a keyed network. Caller holds
  // n.publish_mutex (or owns the network alone).
  template <typename T>
  int publish_typed(Network& n, const char* channel, const T& m) {
    if (!n.signer) return n.lcm->publish(channel, &m);
    const int size = m.getEncodedSize();
    if (size < 0) return -1;
    n.scratch.resize(static_cast<std::size_t>(size) + kAuthTrailerBytes);
    if (m.encode(n.scratch.data(), 0, size) != size) return -1;
    return publish_raw(n, channel, n.scratch.data(), static_cast<std::size_t>(size));
  }

  // Maintenance thread: re-reads changed key files.
  void reload_keys() {
    for (auto& n : networks) {
      if (!n->keys) continue;
      const std::string m = n->keys->check_reload();
      if (!m.empty()) warn("keys " + m, [&] { return "TiMS/LCM: network '" + n->config.name + "': " + m; });
    }
  }

  // ------------------------------------------------------------------ publishing
  // Publishes one TiMS message (host byte order header at the start) on `n`, chunked
  // and compressed as the network says. `writable`: the caller owns `msg` and lets it
  // be used as scratch (restored before return), so that chunks after the first go out
  // in place (the 50-byte prefix written over the tail of the chunk before, which has
  // been sent) instead of being copied into the packet buffer first. Any non-RT thread.
  bool publish_message(Network& n, const std::byte* msg, uint32_t len, int64_t msg_origin, int64_t relay, int8_t hops,
                       int32_t seq, bool writable = false) {
    std::lock_guard lock(n.publish_mutex);
    const std::byte* stream = msg;
    uint32_t encoded = len;
    int8_t encoding = 0;
    if (n.cctx != nullptr && len >= n.config.compress_min_bytes) {
      // Encoding 2: the 16-byte header as it is, then the body as one zstd frame. Every
      // host reads the destination from the first chunk and drops the rest of a message
      // for another host unread (encoding 1, the whole message compressed, made every
      // host on the network reassemble and decompress every compressed message).
      constexpr std::size_t kHead = sizeof(MessageHeader);
      const std::size_t c = ZSTD_compressCCtx(n.cctx, n.compressed.data() + kHead, n.compressed.size() - kHead,
                                              msg + kHead, len - kHead, 1);
      if (ZSTD_isError(c) == 0 && kHead + c < len) {
        std::memcpy(n.compressed.data(), msg, kHead);
        stream = n.compressed.data();
        encoded = static_cast<uint32_t>(kHead + c);
        encoding = 2;
        writable = true;  // our own buffer
        bump(compressed_out);
      }
    }
    bool ok = true;
    for (uint32_t off = 0; off < encoded; off += kChunk) {
      const uint32_t size = std::min(kChunk, encoded - off);
      // Signed packets get a trailer after the chunk: built in the packet buffer.
      const bool in_place = writable && off >= kPacketPrefix && !n.signer;
      std::array<uint8_t, kPacketPrefix> saved{};
      uint8_t* p = nullptr;
      if (in_place) {
        // const_cast: `writable` says the caller owns this memory exclusively.
        p = reinterpret_cast<uint8_t*>(const_cast<std::byte*>(stream + off - kPacketPrefix));
        std::memcpy(saved.data(), p, kPacketPrefix);
      } else {
        p = n.packet.data();
        std::memcpy(p + kPacketPrefix, stream + off, size);
      }
      put_be(p, static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
      put_be(p + kOffOrigin, static_cast<uint64_t>(msg_origin), 8);
      put_be(p + kOffRelay, static_cast<uint64_t>(relay), 8);
      put_be(p + kOffPacketSeq, ++n.packet_seq, 4);
      put_be(p + kOffMessageSeq, static_cast<uint32_t>(seq), 4);
      put_be(p + kOffTotal, len, 4);
      put_be(p + kOffEncoded, encoded, 4);
      put_be(p + kOffOffset, off, 4);
      p[kOffEncoding] = static_cast<uint8_t>(encoding);
      p[kOffHops] = static_cast<uint8_t>(hops);
      put_be(p + kOffSize, size, 4);
      const int rc = publish_raw(n, kTimsChannel, p, kPacketPrefix + size);
      if (in_place) std::memcpy(p, saved.data(), kPacketPrefix);
      if (rc != 0) {
        bump(publish_errors);
        ok = false;
        warn("publish", [&] { return "TiMS/LCM: publish on " + n.config.url + " failed"; });
        break;
      }
      bump(packets_out);
    }
    if (ok) {
      bump(messages_out);
      bump(bytes_out, len);
      bump(wire_bytes_out, encoded);
    }
    return ok;
  }

  // Networks a message for `dest` leaves on (sender threads).
  template <typename Fn>
  void for_networks_to(Address dest, Fn fn) {
    const uint8_t sys = dest.system();
    bool any_fleet = false;
    for (auto& n : networks) any_fleet = any_fleet || n->config.scope == NetworkScope::kFleet;
    for (auto& n : networks) {
      bool use = true;
      if (sys != kToolSystem && any_fleet && networks.size() > 1) {
        const bool other = sys != own_system || role() == NodeRole::kTopRouter;
        use = (n->config.scope == NetworkScope::kFleet) == other;
      }
      if (use) fn(*n);
    }
  }

  NodeRole role() const { return config.role; }

  // ------------------------------------------------------------------ discovery table
  // Lock held. A component (or executor) address that a live host announced.
  bool known_locked(Address a) const { return owners.count(a.component().raw()) != 0; }

  bool warm() const { return rt::monotonic_ns() - started_ns >= config.warmup_ns; }

  // Lock held. Whether this transport answers NOT_AVAILABLE for unknown mailboxes of
  // `system` (see the header: exactly one authority per system).
  bool authoritative_locked(uint8_t system) const {
    if (system == kToolSystem || role() == NodeRole::kTool || !warm()) return false;
    bool system_router = false, lower_executor = false, lower_top_router = false;
    const int64_t now = rt::monotonic_ns();
    for (const auto& [o, e] : hosts) {
      // Several top routers share a fleet (no single point of failure): the live one
      // with the lowest host id answers, the others stand by until it expires. One
      // heard for less than a warm-up is not answering yet (it has just started): this
      // one goes on answering meanwhile (both may answer for a moment; the requester
      // takes the first reply and drops the second as stale).
      if (e.info.role == NodeRole::kTopRouter && e.info.host_id < own_host_id &&
          now - e.first_seen_ns >= config.warmup_ns) {
        lower_top_router = true;
      }
      if (e.info.system != system) continue;
      if (e.info.role == NodeRole::kSystemRouter) system_router = true;
      if (e.info.role == NodeRole::kExecutor && e.info.host_id < own_host_id) lower_executor = true;
    }
    switch (role()) {
      case NodeRole::kTopRouter: return !system_router && !lower_top_router;
      case NodeRole::kSystemRouter: return system == own_system;
      case NodeRole::kExecutor: return system == own_system && !system_router && !lower_executor;
      case NodeRole::kTool: return false;
    }
    return false;
  }

  // Whether two announcements of a host name the same executor and component addresses
  // (what `owners` maps).
  static bool same_addresses(const HostInfo& a, const HostInfo& b) {
    if (a.executor != b.executor || a.components.size() != b.components.size()) return false;
    for (std::size_t i = 0; i < a.components.size(); ++i) {
      if (a.components[i].address != b.components[i].address) return false;
    }
    return true;
  }

  void rebuild_owners_locked() {
    owners.clear();
    for (const auto& [o, e] : hosts) {
      owners[e.info.executor.component().raw()] = o;
      for (const auto& c : e.info.components) owners[c.address.component().raw()] = o;
    }
  }

  // Lock held. Sends an ERROR, in the producer's name, to every local consumer of a
  // component of `lost` (as the producer would when going OFF) and forgets them.
  void fail_subscriptions_locked(const HostInfo& lost, const std::string& why) {
    std::set<uint32_t> gone;
    gone.insert(lost.executor.component().raw());
    for (const auto& c : lost.components) gone.insert(c.address.component().raw());
    char text[120] = {};
    std::snprintf(text, sizeof text, "host '%s' lost: %s", lost.host.c_str(), why.c_str());
    auto it = subscriptions.begin();
    while (it != subscriptions.end()) {
      if (gone.count(it->producer) == 0) {
        ++it;
        continue;
      }
      const MessageHeader h = make_header(Address(it->listener), Address(it->producer), msg::kError, it->priority, 0,
                                          sizeof text);
      const ConstBuffer part{text, sizeof text};
      (void)router.send(h, std::span<const ConstBuffer>(&part, 1));
      bump(subscriptions_failed);
      it = subscriptions.erase(it);
    }
    for (auto st = streams.begin(); st != streams.end();) {
      const auto listener = static_cast<uint32_t>(st->first);
      if (gone.count(Address(listener).component().raw()) == 0) {
        ++st;
        continue;
      }
      const Address producer(static_cast<uint32_t>(st->first >> 32));
      const uint32_t body[2] = {listener, 0};  // rack::wire::StopContDataRequest
      const MessageHeader h = make_header(producer, control.address(), msg::kStopContData, 0, 0, sizeof body);
      const ConstBuffer part{body, sizeof body};
      (void)router.send(h, std::span<const ConstBuffer>(&part, 1));
      bump(streams_stopped);
      st = streams.erase(st);
    }
  }

  void expire_hosts() {
    std::vector<std::pair<std::string, std::string>> lines;  // rate-limit key (the host), text
    {
      std::lock_guard lock(table_mutex);
      const int64_t now = rt::monotonic_ns();
      bool changed = false;
      for (auto it = hosts.begin(); it != hosts.end();) {
        const int64_t silent = now - it->second.info.last_seen_ns;
        if (silent <= config.expiry_ns) {
          ++it;
          continue;
        }
        const HostInfo& info = it->second.info;
        lines.emplace_back(
            "expired " + info.host + " " + std::to_string(info.system) + "/" + std::to_string(info.host_id),
            "TiMS/LCM: host '" + info.host + "' (system " + std::to_string(info.system) + ", host id " +
                std::to_string(info.host_id) + ", pid " + std::to_string(info.pid) + ", " + describe(info.role) +
                ") expired: no announcement for " + std::to_string(silent / rt::kNsPerMs) + " ms");
        fail_subscriptions_locked(info, "no announcement for " + std::to_string(silent / rt::kNsPerMs) + " ms");
        bump(hosts_expired);
        it = hosts.erase(it);
        changed = true;
      }
      if (changed) rebuild_owners_locked();
    }
    // Each host at most once a second (one that comes and goes is counted into its next
    // line), and at most kMaxExpiredLines lines per pass: a fleet that drops off the
    // network at once (a switch restarts) is one line more, not hundreds.
    constexpr std::size_t kMaxExpiredLines = 8;
    for (std::size_t i = 0; i < lines.size() && i < kMaxExpiredLines; ++i) {
      warn(lines[i].first, [&] { return lines[i].second; });
    }
    if (lines.size() > kMaxExpiredLines) {
      const std::size_t more = lines.size() - kMaxExpiredLines;
      warn("expired more", [&] {
        return "TiMS/LCM: " + std::to_string(more) +
               " more host(s) expired at the same time (counted in hosts_expired)";
      });
    }
  }

  // ------------------------------------------------------------------ receiving
  // Every refusal of malformed input: counted in `malformed` and in the counter of its
  // kind (LCM framing, announcement, discover request, TiMS packet or message), and
  // logged at most once a second per kind with the reason.
  void reject(Network& n, const std::string& kind, const std::function<std::string()>& why) {
    bump(malformed);
    bump(kind == "lcm"        ? malformed_lcm
         : kind == "announce" ? malformed_announce
         : kind == "discover" ? malformed_discover
                              : malformed_packet);
    warn("malformed " + kind, [&] {
      return "TiMS/LCM: dropped a malformed packet on network '" + n.config.name + "' (" + n.config.url + "): " + why();
    });
  }

  void count_gap(Network& n, int64_t publisher, uint32_t seq) {
    if (n.last_packet_seq.size() > 4096) n.last_packet_seq.clear();  // bounded; a restart of counting
    auto [it, fresh] = n.last_packet_seq.try_emplace(publisher, seq);
    if (fresh) return;
    const uint32_t expected = it->second + 1;
    const uint32_t ahead = seq - expected;  // modulo 2^32
    if (ahead != 0 && ahead < (1u << 20)) bump(sequence_gaps, ahead);
    if (ahead < (1u << 31)) it->second = seq;  // ignore late (reordered) packets
  }

  void report_lost(Network& n, Reassembly& s, const char* why) {
    bump(lost_messages);
    std::string what = "message " + std::to_string(s.message_seq) + " of origin " + origin_text(s.origin);
    if (s.have[0] != 0 && s.encoding != 1 && s.total >= sizeof(MessageHeader)) {
      MessageHeader h;
      if (decode_header(std::span<const std::byte>(s.data.data(), s.total), h) != MessageError::kOk) {
        // decode_header checks the length too, which is the full one here: read raw.
        std::memcpy(&h, s.data.data(), sizeof h);
      }
      what = "message from " + h.source().str() + " to " + h.destination().str();
    }
    const uint32_t received = s.received;
    const uint32_t chunks = s.chunks;
    const uint32_t total = s.total;
    warn("lost", [&] {
      return "TiMS/LCM: " + what + " (" + std::to_string(total) + " bytes) lost on network '" + n.config.name +
             "': " + std::to_string(chunks - received) + " of " + std::to_string(chunks) + " chunks missing (" + why +
             "); raise recv_buf_size in the LCM URL and net.core.rmem_max";
    });
    s.used = false;
  }

  void expire_reassembly(Network& n) {
    const int64_t now = rt::monotonic_ns();
    for (auto& s : n.slots) {
      if (s.used && now - s.started_ns > config.reassembly_timeout_ns) report_lost(n, s, "timed out");
    }
  }

  // Where a chunk's bytes go: nowhere (dropped, counted as the checks say), a
  // single-chunk message (handled from the datagram), or a reassembly slot at `offset`.
  struct ChunkPlan {
    enum Kind : uint8_t { kDrop, kSingle, kSlot } kind = kDrop;
    Reassembly* slot = nullptr;
    uint32_t offset = 0;
    uint32_t size = 0;
  };

  // A whole datagram's tims_packet (from LCM, or read whole from our socket).
  void on_packet(Network& n, const uint8_t* d, std::size_t size, const std::string& channel) {
    const ChunkPlan plan = plan_chunk(n, d, size, channel);
    if (plan.kind == ChunkPlan::kSingle) {
      const int32_t total = get_i32(d + kOffTotal);
      return take_stream(n, reinterpret_cast<const std::byte*>(d + kPacketPrefix), false, plan.size,
                         static_cast<uint32_t>(total), static_cast<int8_t>(d[kOffEncoding]), get_i64(d + kOffOrigin),
                         get_i32(d + kOffMessageSeq), static_cast<int8_t>(d[kOffHops]));
    }
    if (plan.kind != ChunkPlan::kSlot) return;
    std::memcpy(plan.slot->data.data() + plan.offset, d + kPacketPrefix, plan.size);
    finish_chunk(n, *plan.slot);
  }

  // Validates a tims_packet of `size` bytes of which the prefix and, for a first chunk,
  // the message header are at `d` (the rest of the chunk may still be in the socket),
  // and says where its bytes go. A chunk planned into a slot is marked received there:
  // the caller copies it and calls finish_chunk().
  ChunkPlan plan_chunk(Network& n, const uint8_t* d, std::size_t size, const std::string& channel) {
    bump(packets_in);
    if (size < kPacketPrefix) {
      return rejected(n, "short", [&] {
        return "'" + channel + "': " + std::to_string(size) + " bytes, shorter than a tims_packet";
      });
    }
    if (get_be(d, 8) != static_cast<uint64_t>(rack_lcm::tims_packet::getHash())) {
      return rejected(n, "type", [&] { return "'" + channel + "': not a rack_lcm.tims_packet (fingerprint differs)"; });
    }
    const int64_t pkt_origin = get_i64(d + kOffOrigin);
    const int64_t relay = get_i64(d + kOffRelay);
    const auto pseq = static_cast<uint32_t>(get_i32(d + kOffPacketSeq));
    const int32_t mseq = get_i32(d + kOffMessageSeq);
    const int32_t total = get_i32(d + kOffTotal);
    const int32_t encoded = get_i32(d + kOffEncoded);
    const int32_t offset = get_i32(d + kOffOffset);
    const auto encoding = static_cast<int8_t>(d[kOffEncoding]);
    const auto hops = static_cast<int8_t>(d[kOffHops]);
    const int32_t chunk = get_i32(d + kOffSize);
    if (static_cast<int64_t>(chunk) != static_cast<int64_t>(size - kPacketPrefix)) {
      return rejected(n, "size", [&] {
        return "size field " + std::to_string(chunk) + " but " + std::to_string(size - kPacketPrefix) + " bytes follow";
      });
    }
    if (pkt_origin == origin || relay == origin) return {};  // our own packet, back over multicast
    count_gap(n, relay != 0 ? relay : pkt_origin, pseq);
    const uint32_t max_encoded = static_cast<uint32_t>(n.slots[0].data.size());
    if (total < static_cast<int32_t>(sizeof(MessageHeader)) ||
        static_cast<uint32_t>(total) > config.max_message_bytes || encoded < 0 ||
        static_cast<uint32_t>(encoded) > max_encoded || offset < 0 || static_cast<uint32_t>(offset) % kChunk != 0 ||
        static_cast<int64_t>(offset) + chunk > encoded ||
        (static_cast<int64_t>(offset) + chunk != encoded && static_cast<uint32_t>(chunk) != kChunk) || encoding < 0 ||
        encoding > 2 || (encoding == 0 && encoded != total) ||
        (encoding == 2 && encoded <= static_cast<int32_t>(sizeof(MessageHeader))) || hops < 0 || hops > kMaxHops) {
      return rejected(n, "fields", [&] {
        return "bad chunk fields (total " + std::to_string(total) + ", encoded " + std::to_string(encoded) +
               ", offset " + std::to_string(offset) + ", size " + std::to_string(chunk) + ", encoding " +
               std::to_string(encoding) + ", hops " + std::to_string(hops) + ", limit " +
               std::to_string(config.max_message_bytes) + " bytes)";
      });
    }
    const auto* data = reinterpret_cast<const std::byte*>(d + kPacketPrefix);
    if (offset == 0 && chunk == encoded) {  // one chunk: the common case
      return {ChunkPlan::kSingle, nullptr, 0, static_cast<uint32_t>(chunk)};
    }
    for (const auto& k : n.skipped) {
      if (k.first == pkt_origin && k.second == mseq && pkt_origin != 0) return {};
    }
    Reassembly* slot = nullptr;
    for (auto& s : n.slots) {
      if (s.used && s.origin == pkt_origin && s.message_seq == mseq) slot = &s;
    }
    if (offset == 0 && encoding != 1 && !wants(data, static_cast<std::size_t>(chunk))) {
      bump(not_for_us);
      n.skipped[n.next_skipped] = {pkt_origin, mseq};
      n.next_skipped = (n.next_skipped + 1) % n.skipped.size();
      if (slot != nullptr) slot->used = false;  // chunks that came before the first
      return {};
    }
    if (slot == nullptr) {
      for (auto& s : n.slots) {
        if (!s.used) {
          slot = &s;
          break;
        }
      }
      if (slot == nullptr) {  // all busy: the oldest gives way
        slot = &n.slots[0];
        for (auto& s : n.slots) {
          if (s.started_ns < slot->started_ns) slot = &s;
        }
        report_lost(n, *slot, "displaced by newer messages");
      }
      slot->used = true;
      slot->origin = pkt_origin;
      slot->message_seq = mseq;
      slot->total = static_cast<uint32_t>(total);
      slot->encoded = static_cast<uint32_t>(encoded);
      slot->encoding = encoding;
      slot->hops = hops;
      slot->chunks = (static_cast<uint32_t>(encoded) + kChunk - 1) / kChunk;
      slot->received = 0;
      slot->started_ns = rt::monotonic_ns();
      std::fill(slot->have.begin(), slot->have.end(), 0);
    } else if (slot->total != static_cast<uint32_t>(total) || slot->encoded != static_cast<uint32_t>(encoded) ||
               slot->encoding != encoding) {
      reject(n, "chunk", [&] { return std::string("a chunk disagrees with its message's first chunk"); });
      return {};
    }
    const uint32_t index = static_cast<uint32_t>(offset) / kChunk;
    if (index >= slot->have.size()) {  // cannot happen after the checks above; belt and braces
      reject(n, "chunk", [&] { return "chunk index " + std::to_string(index) + " out of range"; });
      return {};
    }
    if (slot->have[index] != 0) return {};  // duplicate
    slot->have[index] = 1;
    ++slot->received;
    return {ChunkPlan::kSlot, slot, static_cast<uint32_t>(offset), static_cast<uint32_t>(chunk)};
  }

  ChunkPlan rejected(Network& n, const std::string& kind, const std::function<std::string()>& why) {
    reject(n, kind, why);
    return {};
  }

  // A chunk's bytes are in its slot: hands the message on when it is complete.
  void finish_chunk(Network& n, Reassembly& slot) {
    if (slot.received != slot.chunks) return;
    slot.used = false;
    take_stream(n, slot.data.data(), true, slot.encoded, slot.total, slot.encoding, slot.origin, slot.message_seq,
                slot.hops);
  }

  // A planned chunk that did not arrive after all (the socket read failed): the slot
  // waits for it again, as for a lost datagram.
  void unplan_chunk(Reassembly& slot, uint32_t offset) {
    slot.have[offset / kChunk] = 0;
    --slot.received;
  }

  // Whether a message whose first bytes (its header, any byte order) are `head` is worth
  // reassembling here: for a local mailbox, or anything when this host routes, or a
  // request this host may have to answer NOT_AVAILABLE.
  bool wants(const std::byte* head, std::size_t size) {
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

  // A whole encoded message: decode it (into n.message, or in place when `stream` is
  // our own reassembly buffer: a 4 MiB message is not copied once more), then handle it.
  void take_stream(Network& n, const std::byte* stream, bool own_buffer, uint32_t encoded, uint32_t total,
                   int8_t encoding, int64_t msg_origin, int32_t mseq, int8_t hops) {
    if (encoding == 1) {
      const unsigned long long size = ZSTD_getFrameContentSize(stream, encoded);
      if (size != total) {
        return reject(n, "zstd",
                      [&] { return std::string("compressed message whose frame size differs from its total"); });
      }
      const std::size_t got = ZSTD_decompressDCtx(n.dctx, n.message.data(), total, stream, encoded);
      if (ZSTD_isError(got) != 0 || got != total) {
        return reject(n, "zstd", [&] {
          return std::string("compressed message does not decompress: ") +
                 (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size");
        });
      }
    } else if (encoding == 2) {
      // The header as it is, then the body's frame (encoded > 16: checked on receipt).
      constexpr std::size_t kHead = sizeof(MessageHeader);
      if (!wants(stream, encoded)) {  // a one-chunk message for another host: not decompressed
        bump(not_for_us);
        return;
      }
      const std::size_t body = total - kHead;
      const unsigned long long size = ZSTD_getFrameContentSize(stream + kHead, encoded - kHead);
      if (total < kHead || size != body) {
        return reject(n, "zstd",
                      [&] { return std::string("compressed body whose frame size differs from its total"); });
      }
      std::memcpy(n.message.data(), stream, kHead);
      const std::size_t got = ZSTD_decompressDCtx(n.dctx, n.message.data() + kHead, body, stream + kHead,
                                                  encoded - kHead);
      if (ZSTD_isError(got) != 0 || got != body) {
        return reject(n, "zstd", [&] {
          return std::string("compressed body does not decompress: ") +
                 (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size");
        });
      }
    } else if (own_buffer) {
      return handle_message(n, const_cast<std::byte*>(stream), total, msg_origin, mseq, hops);
    } else {
      std::memcpy(n.message.data(), stream, total);
    }
    handle_message(n, n.message.data(), total, msg_origin, mseq, hops);
  }

  void handle_message(Network& n, std::byte* msg, uint32_t len, int64_t msg_origin, int32_t mseq, int8_t hops) {
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

  int32_t next_message_seq() { return message_seq.fetch_add(1, std::memory_order_relaxed) + 1; }

  // Routers: relays a message heard on `in` to the networks where it belongs.
  bool forward_message(Network& in, const std::byte* msg, const MessageHeader& h, uint32_t len, int64_t msg_origin,
                       int32_t mseq, int8_t hops) {
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

  bool should_forward(NetworkScope from, NetworkScope to, uint8_t dest_system) const {
    if (from == to) return false;
    if (dest_system == kToolSystem) return true;
    if (from == NetworkScope::kRobot) return dest_system != own_system;  // leaves the robot
    return dest_system == own_system;                                    // enters the robot
  }

  // ------------------------------------------------------------------ announcements
  void on_announce(Network& n, const uint8_t* d, std::size_t size, const std::string&) {
    // lcm_wire.h: every string and the component count checked before anything is
    // allocated (lcm-gen's decoder throws on a string length of 0).
    rack_lcm::host_announce a;
    std::string why;
    if (wire_lcm::decode(d, size, a, why) < 0) {
      return reject(n, "announce", [&] { return "announcement of " + std::to_string(size) + " bytes: " + why; });
    }
    if (a.system < 0 || a.system > 254 || a.host_id < 0 || a.host_id > 255 || a.role < 0 || a.role > 2 || a.hops < 0 ||
        a.hops > kMaxHops) {
      return reject(n, "announce", [&] {
        return "announcement with fields out of range (system " + std::to_string(a.system) + ", host_id " +
               std::to_string(a.host_id) + ", role " + std::to_string(a.role) + ", hops " + std::to_string(a.hops) +
               ")";
      });
    }
    // Names go to terminals (rackctl list, hosts) and browsers (rack-gui): a host file
    // cannot hold control characters, so an announcement that does is refused.
    bool has_control = wire_lcm::has_control(a.host);
    for (const auto& c : a.components) {
      has_control = has_control || wire_lcm::has_control(c.name) || wire_lcm::has_control(c.impl);
    }
    if (has_control) {
      return reject(n, "announce", [&] { return std::string("announcement with a control character in a name"); });
    }
    if (a.origin == origin || a.relay == origin) return;  // our own
    HostInfo info;
    info.host = a.host;
    info.system = static_cast<uint8_t>(a.system);
    info.host_id = static_cast<uint8_t>(a.host_id);
    info.role = static_cast<NodeRole>(a.role);
    info.pid = a.pid;
    info.origin = a.origin;
    info.executor = Address(static_cast<uint32_t>(a.executor));
    info.last_seen_ns = rt::monotonic_ns();
    info.network = n.config.name;
    for (const auto& c : a.components) {
      info.components.push_back({Address(static_cast<uint32_t>(c.address)), c.name, c.impl});
    }
    std::string replaced, conflict;
    bool full = false, owners_changed = false;
    {
      std::lock_guard lock(table_mutex);
      const auto same_id = [&](const HostInfo& h) {
        return h.system == info.system && h.host_id == info.host_id && h.role == info.role;
      };
      if (have_own_id && role() != NodeRole::kTool && info.system == own_system && info.host_id == own_host_id &&
          info.role == role()) {
        conflict = "TiMS/LCM: host '" + info.host + "' (pid " + std::to_string(info.pid) +
                   ") announces this host's own system " + std::to_string(own_system) + " and host id " +
                   std::to_string(own_host_id) + ": give every computer of a robot its own host_id";
      }
      // Same host (system and host id), new origin: it restarted. What we knew of the
      // old one is gone now, not only after the expiry. Unless the "old" one is still
      // alive: an origin we retired that announces again, or that a retired one
      // replaced, means two hosts share the id (a configuration error, reported).
      for (auto it = hosts.begin(); it != hosts.end();) {
        const HostInfo& old = it->second.info;
        if (it->first == a.origin || !same_id(old)) {
          ++it;
          continue;
        }
        if (retired.count(a.origin) != 0 || retired.count(it->first) != 0) {
          conflict = "TiMS/LCM: two hosts announce system " + std::to_string(info.system) + " host id " +
                     std::to_string(info.host_id) + ": '" + old.host + "' (pid " + std::to_string(old.pid) + ") and '" +
                     info.host + "' (pid " + std::to_string(info.pid) +
                     "): give every computer of a robot its own host_id";
          ++it;
          continue;
        }
        replaced = "TiMS/LCM: host '" + old.host + "' (system " + std::to_string(old.system) + ", host id " +
                   std::to_string(old.host_id) + ") restarted: pid " + std::to_string(old.pid) + " -> " +
                   std::to_string(info.pid);
        if (retired.size() > 1024) retired.clear();
        retired.insert(it->first);
        fail_subscriptions_locked(old, "restarted");
        bump(hosts_expired);
        it = hosts.erase(it);
        owners_changed = true;
      }
      if (hosts.size() >= kMaxHosts && hosts.count(a.origin) == 0) {
        bump(hosts_refused);
        full = true;
      } else {
        auto& e = hosts[a.origin];
        if (e.first_seen_ns == 0) {
          e.first_seen_ns = info.last_seen_ns;
          owners_changed = true;
        } else if (!same_addresses(e.info, info)) {
          owners_changed = true;
        }
        e.info = std::move(info);
      }
      // Only when a host came, went or changed its components: the periodic
      // announcement of a known host (nearly all of them) costs a look-up, not a
      // rebuild of the whole fleet's table (which made every host's work per second
      // grow with the square of the fleet).
      if (owners_changed) rebuild_owners_locked();
    }
    if (full) {
      return warn("hosts full " + n.config.name, [&] {
        return "TiMS/LCM: refused an announcement of host '" + a.host + "' (origin " + origin_text(a.origin) +
               ") on network '" + n.config.name + "': " + std::to_string(kMaxHosts) +
               " hosts known already (a flood of made-up hosts?)";
      });
    }
    if (!replaced.empty()) warn("restart " + replaced, [&] { return replaced; });
    if (!conflict.empty()) {
      warn("conflict " + std::to_string(a.system) + "/" + std::to_string(a.host_id), [&] { return conflict; });
    }
    // Routers pass announcements on: a robot's own outwards, other robots' inwards.
    if ((role() == NodeRole::kSystemRouter || role() == NodeRole::kTopRouter) && a.hops < kMaxHops) {
      for (auto& out : networks) {
        // The opposite direction of messages: a robot's own hosts are made known to
        // the fleet, other robots' hosts to the robot.
        if (out.get() == &n || n.config.scope == out->config.scope) continue;
        const bool own = static_cast<uint8_t>(a.system) == own_system;
        if (own != (n.config.scope == NetworkScope::kRobot)) continue;
        rack_lcm::host_announce f = a;
        f.relay = origin;
        f.hops = static_cast<int8_t>(a.hops + 1);
        std::lock_guard lock(out->publish_mutex);
        if (publish_typed(*out, kAnnounceChannel, f) != 0) bump(publish_errors);
      }
    }
  }

  // A discover request is answered with this host's announcement on the network it
  // came from, at most once per discover_answer_interval_ns there: requests that come
  // while an answer is due or was just sent share it (coalesced, counted as
  // suppressed), so a flood of requests costs one announcement per interval, not one
  // each. A periodic announcement answers them too. Routers pass on only requests
  // that were not coalesced.
  void on_discover(Network& n, const uint8_t* d, std::size_t size, const std::string&) {
    rack_lcm::discover_request r;
    std::string why;
    if (wire_lcm::decode(d, size, r, why) < 0) {
      return reject(n, "discover", [&] { return "discover request of " + std::to_string(size) + " bytes: " + why; });
    }
    if (r.hops < 0 || r.hops > kMaxHops) {
      return reject(n, "discover", [&] { return "discover request with " + std::to_string(r.hops) + " hops"; });
    }
    if (r.origin == origin || r.relay == origin) return;
    bool answer_now = false;
    {
      std::lock_guard lock(announce_mutex);
      if (have_announcement) {
        if (n.answer_pending || rt::monotonic_ns() - n.last_announce_ns < config.discover_answer_interval_ns) {
          if (n.answer_pending) {
            bump(discovers_suppressed);
            return;
          }
          n.answer_pending = true;  // the maintenance thread answers when the interval has passed
        } else {
          answer_now = true;
        }
        bump(discovers_answered);
      }
    }
    if (answer_now) publish_announcement(&n);
    if ((role() == NodeRole::kSystemRouter || role() == NodeRole::kTopRouter) && r.hops < kMaxHops) {
      for (auto& out : networks) {
        if (out.get() == &n) continue;
        rack_lcm::discover_request f = r;
        f.relay = origin;
        f.hops = static_cast<int8_t>(r.hops + 1);
        std::lock_guard lock(out->publish_mutex);
        if (publish_typed(*out, kDiscoverChannel, f) != 0) bump(publish_errors);
      }
    }
  }

  // The maintenance thread: answers the coalesced discover requests whose interval has
  // passed.
  void answer_pending_discovers() {
    for (auto& n : networks) {
      bool due = false;
      {
        std::lock_guard lock(announce_mutex);
        due = n->answer_pending && rt::monotonic_ns() - n->last_announce_ns >= config.discover_answer_interval_ns;
      }
      if (due) publish_announcement(n.get());
    }
  }

  // On one network, or on all (nullptr).
  void publish_announcement(Network* only) {
    std::lock_guard lock(announce_mutex);
    if (!have_announcement) return;
    announcement.time_ns = rt::host_time_ns();
    const int64_t now = rt::monotonic_ns();
    for (auto& n : networks) {
      if (only != nullptr && n.get() != only) continue;
      n->last_announce_ns = now;  // answers every discover request heard so far
      n->answer_pending = false;
      std::lock_guard plock(n->publish_mutex);
      if (publish_typed(*n, kAnnounceChannel, announcement) != 0) bump(publish_errors);
    }
  }

  // ------------------------------------------------------------------ threads
  // The last line of defence of a receive thread: the decoders are total (lcm_wire.h)
  // and every field is checked, but whatever still throws while one datagram is handled
  // (an allocation failure) ends that datagram, counted and logged, not the process.
  template <typename Fn>
  void guarded(Network& n, Fn fn) noexcept {
    try {
      fn();
    } catch (const std::exception& e) {
      const std::string what = e.what();
      reject(n, "exception", [&] { return "handling a datagram failed: " + what; });
    } catch (...) {
      reject(n, "exception", [&] { return std::string("handling a datagram failed"); });
    }
  }

  void receive_loop(Network& n) {
    pollfd pfd{n.raw_fd >= 0 ? n.raw_fd : n.lcm->getFileno(), POLLIN, 0};
    while (running.load(std::memory_order_acquire)) {
      pfd.revents = 0;
      const int rc = poll(&pfd, 1, 50);
      if (rc > 0 && (pfd.revents & POLLIN) != 0) {
        guarded(n, [&] {
          if (n.raw_fd < 0) {
            n.lcm->handle();
          } else {
            // Drain what is there; a burst (a large message) is many datagrams.
            for (int i = 0; i < 256; ++i) {
              if (!read_datagram(n)) break;
            }
          }
        });
      }
      expire_reassembly(n);
    }
  }

  void maintenance_loop() {
    int64_t next_announce = rt::monotonic_ns() + config.announce_period_ns;
    int64_t next_key_check = rt::monotonic_ns() + rt::kNsPerSec;
    while (running.load(std::memory_order_acquire)) {
      rt::sleep_for(50 * rt::kNsPerMs);
      if (rt::monotonic_ns() >= next_key_check) {
        reload_keys();
        next_key_check = rt::monotonic_ns() + rt::kNsPerSec;
      }
      if (config.announce_period_ns > 0 && rt::monotonic_ns() >= next_announce) {
        publish_announcement(nullptr);
        next_announce = rt::monotonic_ns() + config.announce_period_ns;
      }
      answer_pending_discovers();
      expire_hosts();
      while (control.peek(Mailbox::kNonBlocking).status == RecvStatus::kOk) control.peek_end();
    }
  }

  void forget_subscription_locked(uint32_t producer, uint32_t listener) {
    subscriptions.erase(
        std::remove_if(subscriptions.begin(), subscriptions.end(),
                       [&](const Subscription& s) { return s.producer == producer && s.listener == listener; }),
        subscriptions.end());
  }

  // Remembers GET_CONT_DATA/STOP_CONT_DATA that leave this host, so that local
  // consumers learn of a lost producer host. Body layouts: rack::wire::ContDataRequest
  // (int64 period, uint32 mailbox) and StopContDataRequest (uint32 mailbox), native.
  void track_subscription_locked(const MessageHeader& h, std::span<const std::byte> body) {
    if (h.type == msg::kGetContData && body.size() >= 12) {
      uint32_t mailbox = 0;
      std::memcpy(&mailbox, body.data() + 8, 4);
      const uint32_t producer = h.destination().component().raw();
      forget_subscription_locked(producer, mailbox);
      if (subscriptions.size() < 4096) subscriptions.push_back({producer, mailbox, h.priority});
    } else if (h.type == msg::kStopContData && body.size() >= 4) {
      uint32_t mailbox = 0;
      std::memcpy(&mailbox, body.data(), 4);
      forget_subscription_locked(h.destination().component().raw(), mailbox);
    }
  }

  void send_loop(Mailbox& box) {
    while (running.load(std::memory_order_acquire)) {
      const auto p = box.peek(100 * rt::kNsPerMs);
      if (p.status == RecvStatus::kClosed) break;
      if (p.status != RecvStatus::kOk) continue;
      const MessageHeader h = *p.header;
      const auto* bytes = reinterpret_cast<const std::byte*>(p.header);
      bool answer_na = false, drop = false;
      {
        std::lock_guard lock(table_mutex);
        track_subscription_locked(h, p.body);
        if (h.type == msg::kData && router.find(h.source()) != nullptr) {
          const uint64_t key = (uint64_t{h.source().component().raw()} << 32) | h.dest;
          if (streams.size() < 4096 || streams.count(key) != 0) streams[key] = rt::monotonic_ns();
        }
        if (h.destination().system() != kToolSystem && !known_locked(h.destination()) &&
            authoritative_locked(h.destination().system())) {
          (h.is_request() ? answer_na : drop) = true;
        }
      }
      if (answer_na || drop) {
        box.peek_end();
        if (answer_na) {
          bump(not_available);
          const MessageHeader reply = make_reply_header(h, msg::kNotAvailable, 0);
          (void)router.send(reply, std::span<const ConstBuffer>{});
        } else {
          bump(not_for_us);
        }
        continue;
      }
      const int32_t seq = next_message_seq();
      // The peeked slot is ours until peek_end(): chunks may go out in place.
      for_networks_to(h.destination(),
                      [&](Network& n) { (void)publish_message(n, bytes, h.length, origin, 0, 0, seq, true); });
      box.peek_end();
      notify_drained();
    }
  }

  uint32_t uplink_queued() const { return uplink.queued() + large_uplink.queued(); }

  void notify_drained() {
    const int64_t threshold = drain_threshold.load(std::memory_order_acquire);
    if (threshold < 0 || uplink_queued() > threshold) return;
    std::lock_guard lock(drain_mutex);
    drained.notify_all();
  }
};

LcmTransport::LcmTransport(Router& router, LcmTransportConfig config)
    : impl_(std::make_unique<Impl>(router, std::move(config))) {
  impl_->join();
}

LcmTransport::~LcmTransport() { stop(); }

void LcmTransport::start() {
  Impl& m = *impl_;
  if (m.running.exchange(true)) return;
  m.started_ns = rt::monotonic_ns();
  m.router.set_uplink(&m.uplink, &m.large_uplink);
  m.router.add(m.control);
  for (auto& n : m.networks) {
    Impl::Network* net = n.get();
    // Named for top/ps on a robot (and bench_lcm's CPU accounting).
    net->receiver = std::thread([&m, net] {
      pthread_setname_np(pthread_self(), "tims-rx");
      if (const int prio = m.config.receive_priority; prio > 0) {
        if (const int err = rt::set_current_thread_priority(prio); err != 0) {
          m.warn("rx priority " + net->config.name, [&] {
            return "TiMS/LCM: the receive thread of network '" + net->config.name +
                   "' cannot run at SCHED_FIFO priority " + std::to_string(prio) + " (" + std::strerror(err) +
                   "): it stays at normal scheduling";
          });
        }
      }
      m.receive_loop(*net);
    });
  }
  m.sender = std::thread([&m] {
    pthread_setname_np(pthread_self(), "tims-tx");
    m.send_loop(m.uplink);
  });
  m.large_sender = std::thread([&m] {
    pthread_setname_np(pthread_self(), "tims-tx-large");
    m.send_loop(m.large_uplink);
  });
  m.maintenance = std::thread([&m] {
    pthread_setname_np(pthread_self(), "tims-maint");
    m.maintenance_loop();
  });
  m.publish_announcement(nullptr);
  request_discovery();
}

void LcmTransport::stop() {
  if (!impl_ || !impl_->running.exchange(false)) return;
  Impl& m = *impl_;
  m.router.set_uplink(nullptr);
  m.uplink.close();
  m.large_uplink.close();
  m.router.remove(m.control.address());
  for (auto& n : m.networks) {
    if (n->receiver.joinable()) n->receiver.join();
  }
  if (m.sender.joinable()) m.sender.join();
  if (m.large_sender.joinable()) m.large_sender.join();
  if (m.maintenance.joinable()) m.maintenance.join();
}

void LcmTransport::set_announcement(HostInfo info) {
  Impl& m = *impl_;
  {
    std::lock_guard lock(m.announce_mutex);
    auto& a = m.announcement;
    a.origin = m.origin;
    a.relay = 0;
    a.hops = 0;
    a.role = static_cast<int8_t>(m.config.role == NodeRole::kTool ? NodeRole::kExecutor : m.config.role);
    a.period_ns = m.config.announce_period_ns;
    a.host = info.host;
    a.system = info.system;
    a.host_id = info.host_id;
    a.pid = info.pid;
    a.executor = static_cast<int32_t>(info.executor.raw());
    a.components.clear();
    for (const auto& c : info.components) {
      rack_lcm::component_info ci;
      ci.address = static_cast<int32_t>(c.address.raw());
      ci.name = c.name;
      ci.impl = c.impl;
      a.components.push_back(ci);
    }
    a.count = static_cast<int32_t>(a.components.size());
    m.have_announcement = true;
  }
  {
    std::lock_guard lock(m.table_mutex);
    m.own_system = info.system;
    m.own_host_id = info.host_id;
    m.have_own_id = true;
  }
  if (m.running.load()) m.publish_announcement(nullptr);
}

void LcmTransport::request_discovery() {
  Impl& m = *impl_;
  rack_lcm::discover_request req;
  req.origin = m.origin;
  req.relay = 0;
  req.hops = 0;
  req.time_ns = rt::host_time_ns();
  req.requester = "pid " + std::to_string(getpid());
  for (auto& n : m.networks) {
    std::lock_guard lock(n->publish_mutex);
    if (m.publish_typed(*n, kDiscoverChannel, req) != 0) bump(m.publish_errors);
  }
}

bool LcmTransport::wait_uplink(uint32_t max_queued, int64_t timeout_ns) {
  Impl& m = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  std::unique_lock lock(m.drain_mutex);
  // One waiter's threshold at a time is enough for the tools that use this; a second
  // waiter with another threshold still wakes by the timeout's bounded re-checks.
  m.drain_threshold.store(max_queued, std::memory_order_release);
  bool ok = true;
  while (m.uplink_queued() > max_queued) {
    if (!m.running.load()) {  // stopped with messages queued: they will not drain
      ok = false;
      break;
    }
    // The sender reads the threshold after its mailbox changed and notifies under the
    // mutex, so no wake-up is lost; the 10 ms re-check is a bound, not the mechanism.
    if (m.drained.wait_until(lock, std::min(deadline, std::chrono::steady_clock::now() +
                                                          std::chrono::milliseconds(10))) == std::cv_status::timeout &&
        std::chrono::steady_clock::now() >= deadline) {
      ok = m.uplink_queued() <= max_queued;
      break;
    }
  }
  m.drain_threshold.store(-1, std::memory_order_release);
  return ok;
}

void LcmTransport::wait_until_warm() const {
  while (impl_->running.load() && !impl_->warm()) rt::sleep_for(10 * rt::kNsPerMs);
}

std::vector<HostInfo> LcmTransport::hosts() const {
  std::lock_guard lock(impl_->table_mutex);
  std::vector<HostInfo> out;
  for (const auto& [key, e] : impl_->hosts) out.push_back(e.info);
  return out;
}

TransportCounters LcmTransport::counters() const noexcept {
  const Impl& m = *impl_;
  const auto r = [](const std::atomic<uint64_t>& a) { return a.load(std::memory_order_relaxed); };
  TransportCounters c;
  c.packets_in = r(m.packets_in);
  c.packets_out = r(m.packets_out);
  c.messages_in = r(m.messages_in);
  c.messages_out = r(m.messages_out);
  c.malformed = r(m.malformed);
  c.forged = r(m.forged);
  c.not_for_us = r(m.not_for_us);
  c.forwarded = r(m.forwarded);
  c.not_available = r(m.not_available);
  c.sequence_gaps = r(m.sequence_gaps);
  c.lost_messages = r(m.lost_messages);
  c.publish_errors = r(m.publish_errors);
  c.delivery_failed = r(m.delivery_failed);
  c.hosts_expired = r(m.hosts_expired);
  c.subscriptions_failed = r(m.subscriptions_failed);
  c.streams_stopped = r(m.streams_stopped);
  c.compressed_out = r(m.compressed_out);
  c.bytes_out = r(m.bytes_out);
  c.wire_bytes_out = r(m.wire_bytes_out);
  c.auth_failed = r(m.auth_failed);
  c.replayed = r(m.replayed);
  c.malformed_lcm = r(m.malformed_lcm);
  c.malformed_packet = r(m.malformed_packet);
  c.malformed_announce = r(m.malformed_announce);
  c.malformed_discover = r(m.malformed_discover);
  c.lcm_fragments = r(m.lcm_fragments);
  c.hosts_refused = r(m.hosts_refused);
  c.discovers_answered = r(m.discovers_answered);
  c.discovers_suppressed = r(m.discovers_suppressed);
  return c;
}

void LcmTransport::handle_datagram(const uint8_t* data, std::size_t size, std::size_t network) {
  Impl& m = *impl_;
  if (network >= m.networks.size()) return;
  m.guarded(*m.networks[network], [&] { m.on_datagram(*m.networks[network], data, size); });
}

const std::string& LcmTransport::url() const noexcept { return impl_->config.networks.front().url; }
int64_t LcmTransport::origin() const noexcept { return impl_->origin; }

}  // namespace rack::tims
