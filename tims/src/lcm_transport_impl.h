// LcmTransport's insides (internal to tims): the transport that owns the networks and
// the threads, and routes whole messages, built from parts that each hold their own
// state (lcm_transport.h describes the transport itself):
//
//   lcm_transport_packet.h       the tims_packet layout and channel names (no state)
//   lcm_transport_stats.h        TransportStats (the counters), NetworkLog (refusals)
//   lcm_transport_socket.h       LcmSocket: LCM for publishing, our own udpm socket
//   lcm_transport_auth.h         LinkAuth: keys, signing, verifying (link_auth.h glue)
//   lcm_transport_chunks.h       ChunkPublisher, ChunkReassembler: messages <-> packets
//   lcm_transport_discovery.h    Discovery: the host table, announcements, discover
//                                answers, host expiry and restarts
//   lcm_transport_subscriptions.h  RemoteSubscriptions: the flows across hosts that a
//                                lost host ends (part of Discovery)
//   lcm_transport_network.cpp    Network: one network's parts wired together; its
//                                receive path (peek, read, dispatch by channel)
//   lcm_transport_routing.cpp    a whole message: deliver, answer NOT_AVAILABLE,
//                                forward; announcements and discover requests passed on
//   lcm_transport.cpp            set-up, the thread loops, the public LcmTransport calls
//
// Real-time contract: nothing here is RT-safe (set-up and the transport's non-RT
// threads). Thread-safety: as each member's comment says.
#pragma once

#include <atomic>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "lcm_receive.h"
#include "lcm_transport_auth.h"
#include "lcm_transport_chunks.h"
#include "lcm_transport_discovery.h"
#include "lcm_transport_socket.h"
#include "lcm_transport_stats.h"
#include "rack/tims/lcm_transport.h"

namespace rack::tims {

struct LcmTransport::Impl {
  // One network: its socket, authentication, chunk publisher and reassembler, wired to
  // the transport's routing and discovery through the handlers it implements.
  struct Network final : PayloadHandler, PacketOut, MessageSink {
    // Joins the network (throws std::runtime_error naming it, as LcmSocket and
    // LinkAuth do).
    Network(Impl& transport, std::size_t net_index, const NetworkConfig& net_config);

    Impl& impl;
    const std::size_t index;
    const NetworkConfig config;
    NetworkLog log;
    LcmSocket socket;
    LinkAuth auth;
    std::mutex publish_mutex;      // the publisher, the signer and LCM's publish
    ChunkPublisher publisher;      // under publish_mutex
    ChunkReassembler reassembler;  // receive thread only
    std::thread receiver;

    // Publishes a TiMS message (ChunkPublisher::publish) under publish_mutex.
    bool publish_message(const std::byte* msg, uint32_t len, int64_t msg_origin, int64_t relay, int8_t hops,
                         int32_t seq, bool writable = false);
    // Publishes an lcm-gen message, signed on a keyed network. Caller holds publish_mutex.
    template <typename T>
    int publish_typed_locked(const char* channel, const T& m) {
      if (!auth.keyed()) return socket.publish(channel, m);
      const std::span<uint8_t> encoded = auth.encode(m);
      if (encoded.empty()) return -1;
      return send_raw_locked(channel, encoded.data(), encoded.size());
    }
    // Signs (keyed network) and publishes raw bytes with room for the trailer after
    // `len`. Caller holds publish_mutex.
    int send_raw_locked(const char* channel, uint8_t* buf, std::size_t len);

    // The receive thread: reads one datagram from the own socket (false: none waiting).
    bool read_datagram();
    // One datagram in LCM's framing (from the own socket, or handle_datagram()).
    void on_datagram(const uint8_t* d, std::size_t size);
    void refuse_fragment(std::size_t size);

    // PayloadHandler: a payload on one of our channels, authenticated, then handed on.
    void on_payload(std::string_view channel, const uint8_t* d, std::size_t size) override;
    // PacketOut: a chunk's packet, signed and published (publish_mutex held).
    int send_packet(uint8_t* buf, std::size_t len) override;
    // MessageSink: the transport's routing.
    bool wants(const std::byte* head, std::size_t size) override;
    void take_message(std::byte* msg, uint32_t len, int64_t msg_origin, int32_t msg_seq, int8_t hops) override;
  };

  Impl(Router& r, LcmTransportConfig c);

  Router& router;
  LcmTransportConfig config;
  const int64_t origin;
  Mailbox uplink;
  Mailbox large_uplink;
  Mailbox control;  // replies to the transport's own requests (STOP_CONT_DATA), drained
  lcm_rx::RateLimitedWarn warn;
  TransportStats stats;
  Discovery discovery;
  std::vector<std::unique_ptr<Network>> networks;
  std::thread sender, large_sender, maintenance;
  // wait_uplink(): the sender threads wake a waiter only when the uplinks have drained
  // to its threshold (one wake-up per batch, not per message).
  std::mutex drain_mutex;
  std::condition_variable drained;
  std::atomic<int64_t> drain_threshold{-1};  // -1: nobody waits
  std::atomic<bool> running{false};
  std::atomic<int32_t> message_seq{0};

  // ------------------------------------------------------------------ small helpers
  NodeRole role() const { return config.role; }
  bool routes() const { return role() == NodeRole::kSystemRouter || role() == NodeRole::kTopRouter; }
  int32_t next_message_seq() { return message_seq.fetch_add(1, std::memory_order_relaxed) + 1; }
  uint32_t uplink_queued() const { return uplink.queued() + large_uplink.queued(); }

  // Networks a message for `dest` leaves on (sender threads).
  template <typename Fn>
  void for_networks_to(Address dest, Fn fn) {
    const uint8_t sys = dest.system();
    bool any_fleet = false;
    for (auto& n : networks) any_fleet = any_fleet || n->config.scope == NetworkScope::kFleet;
    for (auto& n : networks) {
      bool use = true;
      if (sys != kToolSystem && any_fleet && networks.size() > 1) {
        const bool other = sys != discovery.own_system() || role() == NodeRole::kTopRouter;
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
      n.log.reject("exception", [&] { return "handling a datagram failed: " + what; });
    } catch (...) {
      n.log.reject("exception", [&] { return std::string("handling a datagram failed"); });
    }
  }

  // ------------------------------------------------------------------ transport
  // lcm_transport.cpp: set-up, the four thread loops (one receiver per network, two
  // senders, maintenance)
  void join();
  void receive_loop(Network& n);
  void maintenance_loop();
  void send_loop(Mailbox& box);
  void notify_drained();
  void publish_announcement(std::size_t only);  // Discovery::kAll: every network

  // ------------------------------------------------------------------ routing
  // lcm_transport_routing.cpp: a whole message heard: delivered, answered, forwarded or
  // dropped; announcements and discover requests taken and passed on
  bool wants(const std::byte* head, std::size_t size);
  void handle_message(Network& n, std::byte* msg, uint32_t len, int64_t msg_origin, int32_t mseq, int8_t hops);
  bool forward_message(Network& in, const std::byte* msg, const MessageHeader& h, uint32_t len, int64_t msg_origin,
                       int32_t mseq, int8_t hops);
  bool should_forward(NetworkScope from, NetworkScope to, uint8_t dest_system) const;
  void on_announce(Network& n, const uint8_t* d, std::size_t size);
  void on_discover(Network& n, const uint8_t* d, std::size_t size);
};

}  // namespace rack::tims
