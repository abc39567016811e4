// LcmTransport's insides (internal to tims): the state every part shares, and which file
// holds which part of the work. lcm_transport.h describes the transport itself.
//
//   lcm_transport.cpp            set-up, thread loops, the public LcmTransport calls
//   lcm_transport_socket.cpp     our own udpm socket: peek, read into a slot, or drop
//   lcm_transport_chunks.cpp     chunking, compression, reassembly (tims_packet)
//   lcm_transport_auth.cpp       authenticated links (link_auth.h glue)
//   lcm_transport_routing.cpp    a whole message: deliver, answer NOT_AVAILABLE, forward
//   lcm_transport_discovery.cpp  announcements, discover requests, host table and expiry
//
// Real-time contract: nothing here is RT-safe (set-up and the transport's non-RT
// threads). Thread-safety: as each member's comment says (publish_mutex, table_mutex,
// announce_mutex; receive state belongs to its network's receive thread).
#pragma once

#include <lcm/lcm-cpp.hpp>
#include <zstd.h>

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "lcm_receive.h"
#include "lcm_wire.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/link_auth.h"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/host_announce.hpp"
#include "rack_lcm/tims_packet.hpp"

namespace rack::tims {

// Constants and byte helpers of the transport's files.
namespace lcm_detail {

inline constexpr const char* kTimsChannel = "TIMS";
inline constexpr const char* kAnnounceChannel = "TIMS_ANNOUNCE";
inline constexpr const char* kDiscoverChannel = "TIMS_DISCOVER";

// Wire layout of tims_packet (LCM encodes big-endian): 8-byte fingerprint, then the
// fields in declaration order. Offsets of each field:
inline constexpr std::size_t kOffOrigin = 8;
inline constexpr std::size_t kOffRelay = 16;
inline constexpr std::size_t kOffPacketSeq = 24;
inline constexpr std::size_t kOffMessageSeq = 28;
inline constexpr std::size_t kOffTotal = 32;
inline constexpr std::size_t kOffEncoded = 36;
inline constexpr std::size_t kOffOffset = 40;
inline constexpr std::size_t kOffEncoding = 44;
inline constexpr std::size_t kOffHops = 45;
inline constexpr std::size_t kOffSize = 46;
inline constexpr std::size_t kPacketPrefix = 50;
// Bytes of a message per chunk: every LCM datagram stays below LCM's own
// fragmentation limit (about 64 KB), so LCM never reassembles our traffic and a
// receiver knows which message a lost chunk belongs to. Every chunk but the last of a
// message is exactly this long (receivers check it).
inline constexpr uint32_t kChunk = 60000;
// Routers passed before a packet is dropped (a mis-wired fleet must not loop forever).
inline constexpr int8_t kMaxHops = 4;

inline void put_be(uint8_t* p, uint64_t v, int bytes) {
  if (bytes == 8) {
    v = __builtin_bswap64(v);
    std::memcpy(p, &v, 8);
  } else {
    auto w = __builtin_bswap32(static_cast<uint32_t>(v));
    std::memcpy(p, &w, 4);
  }
}
inline uint64_t get_be(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}
inline int64_t get_i64(const uint8_t* p) { return static_cast<int64_t>(get_be(p, 8)); }
inline int32_t get_i32(const uint8_t* p) { return static_cast<int32_t>(static_cast<uint32_t>(get_be(p, 4))); }

inline void bump(std::atomic<uint64_t>& c, uint64_t n = 1) { c.fetch_add(n, std::memory_order_relaxed); }

using wire_lcm::kLcmFragmentMagic;
using wire_lcm::kLcmShortMagic;
// Hosts kept in the discovery table at once: a flood of announcements with made-up
// origins is refused (counted: hosts_refused) instead of growing the table (and the
// work of every announcement) without bound. Far above a fleet's size.
inline constexpr std::size_t kMaxHosts = 256;

inline std::string origin_text(int64_t origin) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(origin));
  return buf;
}

}  // namespace lcm_detail

struct LcmTransport::Impl {
  using RateLimitedWarn = lcm_rx::RateLimitedWarn;

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

  // Where a chunk's bytes go: nowhere (dropped, counted as the checks say), a
  // single-chunk message (handled from the datagram), or a reassembly slot at `offset`.
  struct ChunkPlan {
    enum Kind : uint8_t { kDrop, kSingle, kSlot } kind = kDrop;
    Reassembly* slot = nullptr;
    uint32_t offset = 0;
    uint32_t size = 0;
  };

  Impl(Router& r, LcmTransportConfig c);

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

  // ------------------------------------------------------------------ small helpers
  NodeRole role() const { return config.role; }

  // Lock held. A component (or executor) address that a live host announced.
  bool known_locked(Address a) const { return owners.count(a.component().raw()) != 0; }

  bool warm() const { return rt::monotonic_ns() - started_ns >= config.warmup_ns; }
  int32_t next_message_seq() { return message_seq.fetch_add(1, std::memory_order_relaxed) + 1; }
  uint32_t uplink_queued() const { return uplink.queued() + large_uplink.queued(); }

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

  // ------------------------------------------------------------------ transport
  // lcm_transport.cpp: set-up, the refusal of malformed input, the four thread loops
  // (one receiver per network, two senders, maintenance)
  ~Impl();
  void join();
  void reject(Network& n, const std::string& kind, const std::function<std::string()>& why);
  void receive_loop(Network& n);
  void maintenance_loop();
  void send_loop(Mailbox& box);
  void notify_drained();

  // ------------------------------------------------------------------ socket
  // lcm_transport_socket.cpp: datagrams read from our own udpm socket (peek, then read or drop)
  bool read_datagram(Network& n);
  void read_whole_packet(Network& n, std::size_t at, std::size_t size);
  void on_datagram(Network& n, const uint8_t* d, std::size_t size);
  void refuse_fragment(Network& n, std::size_t size);

  // ------------------------------------------------------------------ auth
  // lcm_transport_auth.cpp: authenticated links (verify and strip, sign, reload key files)
  bool authentic(Network& n, std::string_view channel, const uint8_t* d, std::size_t& size);
  int publish_raw(Network& n, const char* channel, uint8_t* buf, std::size_t len);
  void reload_keys();

  // ------------------------------------------------------------------ chunks
  // lcm_transport_chunks.cpp: messages cut into tims_packet chunks, compressed, reassembled
  bool publish_message(Network& n, const std::byte* msg, uint32_t len, int64_t msg_origin, int64_t relay, int8_t hops,
                       int32_t seq, bool writable = false);
  void count_gap(Network& n, int64_t publisher, uint32_t seq);
  void report_lost(Network& n, Reassembly& s, const char* why);
  void expire_reassembly(Network& n);
  void on_packet(Network& n, const uint8_t* d, std::size_t size, const std::string& channel);
  ChunkPlan plan_chunk(Network& n, const uint8_t* d, std::size_t size, const std::string& channel);
  ChunkPlan rejected(Network& n, const std::string& kind, const std::function<std::string()>& why);
  void finish_chunk(Network& n, Reassembly& slot);
  void unplan_chunk(Reassembly& slot, uint32_t offset);
  void take_stream(Network& n, const std::byte* stream, bool own_buffer, uint32_t encoded, uint32_t total,
                   int8_t encoding, int64_t msg_origin, int32_t mseq, int8_t hops);

  // ------------------------------------------------------------------ routing
  // lcm_transport_routing.cpp: a whole message heard: delivered, answered, forwarded or dropped
  bool wants(const std::byte* head, std::size_t size);
  void handle_message(Network& n, std::byte* msg, uint32_t len, int64_t msg_origin, int32_t mseq, int8_t hops);
  bool forward_message(Network& in, const std::byte* msg, const MessageHeader& h, uint32_t len, int64_t msg_origin,
                       int32_t mseq, int8_t hops);
  bool should_forward(NetworkScope from, NetworkScope to, uint8_t dest_system) const;

  // ------------------------------------------------------------------ discovery
  // lcm_transport_discovery.cpp: the discovery table, announcements, discover requests, host
  // expiry, and the subscriptions a lost host ends
  bool authoritative_locked(uint8_t system) const;
  static bool same_addresses(const HostInfo& a, const HostInfo& b);
  void rebuild_owners_locked();
  void fail_subscriptions_locked(const HostInfo& lost, const std::string& why);
  void expire_hosts();
  void on_announce(Network& n, const uint8_t* d, std::size_t size, const std::string&);
  void on_discover(Network& n, const uint8_t* d, std::size_t size, const std::string&);
  void answer_pending_discovers();
  void publish_announcement(Network* only);
  void forget_subscription_locked(uint32_t producer, uint32_t listener);
  void track_subscription_locked(const MessageHeader& h, std::span<const std::byte> body);
};

}  // namespace rack::tims
