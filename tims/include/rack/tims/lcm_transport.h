// TiMS over LCM: the only place that links LCM (DESIGN.md).
//
// A transport joins one or more LCM networks (a robot's internal bus, a fleet link).
// Per network one non-RT receive thread (validates each packet, delivers it to the
// local router, forwards it when this host is a router, answers NOT_AVAILABLE when it
// is authoritative). On a udpm:// network it reads the datagrams from a socket of its
// own, in LCM's framing, instead of through LCM 1.3's receive thread and notify pipe:
// two thread hand-offs less per message (bench_lcm), and LCM's fragment reassembly,
// which trusts its input, never sees our network (our chunks are single datagrams;
// LCM fragments are refused and counted: lcm_fragments). While large datagrams arrive it peeks at each
// one's head first: what is not for this host is dropped unread, a chunk of a message
// being reassembled is read straight into its slot. LCM still publishes, so lcm-logger and
// lcm-logplayer see and replay the same datagrams. Other URLs (memq://, file://)
// receive through LCM. Two non-RT sender threads drain the
// router's uplink mailboxes (one with many small slots, one with a few large ones)
// and publish. One maintenance thread announces this host and expires silent hosts.
// RT tasks never touch the network: they queue into an uplink mailbox (PI-locked
// bookkeeping, copy outside the lock) and go on.
//
// Channels: "TIMS" (tims_packet chunks), "TIMS_ANNOUNCE" (host_announce),
// "TIMS_DISCOVER" (discover_request). See tims/lcm/rack_tims.lcm.
//
// Routing (RACK's hierarchy on LCM multicast, where every member of a network hears
// every packet and routing means choosing networks and who answers):
//  - an executor delivers what is addressed to its own mailboxes;
//  - a system router joins its robot's network and the fleet network, and forwards
//    between them: robot -> fleet what is addressed to another system (or a tool),
//    fleet -> robot what is addressed to its own system (or a tool); robot-internal
//    traffic never reaches the fleet link. It also forwards announcements the same way;
//  - a top router (base station, on the fleet network) knows every robot and answers
//    NOT_AVAILABLE for what nobody can place.
// A request to a mailbox that no live host announced is answered NOT_AVAILABLE by
// exactly one authority: the system router of the destination's system, else (no
// system router) the top router, else the live executor with the lowest host id of
// that system. Authority starts after a warm-up (the discovery table must be full).
// A fleet may have several top routers (give each its own host_id): the live one with
// the lowest host id answers; when it expires the next takes over, and a restarted one
// with a lower id takes back over after its warm-up (the other stops a warm-up after
// first hearing it, so no request goes unanswered in between). Messages between robots never
// pass a top router (system routers forward them on the fleet link directly), so a
// top router's death costs only these answers, for at most expiry_ns.
//
// Failures: a host expires when it has not announced for `expiry_ns`, or when it is
// replaced (same system and host id, new origin: it restarted). Every local
// subscription (GET_CONT_DATA sent from here) to a component of that host gets an
// ERROR message in the producer's name, as a producer going OFF sends; the consumer
// goes to ERROR and re-subscribes by its own retry when the host returns. In the
// other direction, every local producer that streams to a mailbox of that host gets a
// STOP_CONT_DATA for it, so it does not stream into the void.
//
// Bad input (not LCM, an LCM fragment, not a tims_packet, wrong lengths, bad chunk
// fields, bad header, forged source, own echo with a foreign origin, an announcement or
// discover request that does not decode) is dropped, counted by kind
// (TransportCounters) and logged at most once per second per kind with the reason.
// Announcements and discover requests are decoded by total decoders (tims/src/
// lcm_wire.h), never by lcm-gen's, which throw on a string length of 0. Discover
// requests are answered at most once per discover_answer_interval_ns per network.
//
// Authenticated links: a network with a key file (NetworkConfig::key_file) signs every
// packet it publishes on its channels and drops, counts (auth_failed, replayed) and
// logs every packet that does not verify (rack/tims/link_auth.h). Signing and
// verifying happen in the sender, receive and maintenance threads (never in RT
// tasks). The maintenance thread re-reads a changed key file once a second.
//
// Real-time contract: nothing here is RT-safe; everything is set-up or runs in the
// transport's own non-RT threads. Thread-safety: hosts(), counters(),
// set_announcement(), request_discovery() and wait_uplink() may be called from any
// non-RT thread.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"

namespace rack::tims {

inline constexpr const char* kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0";
// The transport's own mailbox (replies to its STOP_CONT_DATA for lost hosts).
inline constexpr Address kTransportControlAddress = Address::make(kToolSystem, classes::kTool, 0xFF, 0xFD);

enum class NetworkScope : uint8_t {
  kRobot,  // one robot's internal bus: its own system's traffic
  kFleet,  // between robots: other systems' traffic
};
enum class Compression : uint8_t { kNone = 0, kZstd = 1 };
enum class NodeRole : uint8_t {
  kExecutor = 0,      // routes its own mailboxes
  kSystemRouter = 1,  // knows every mailbox of its robot; bridges robot and fleet networks
  kTopRouter = 2,     // knows all robots; answers NOT_AVAILABLE for what nobody can place
  kTool = 3,          // rackctl and other tools: no announcements, never answers for others
};
[[nodiscard]] const char* describe(NetworkScope s) noexcept;
[[nodiscard]] const char* describe(Compression c) noexcept;
[[nodiscard]] const char* describe(NodeRole r) noexcept;

struct NetworkConfig {
  std::string name = "robot";
  std::string url = kDefaultLcmUrl;
  NetworkScope scope = NetworkScope::kRobot;
  Compression compression = Compression::kNone;
  uint32_t compress_min_bytes = 16 * 1024;  // smaller messages are sent as they are
  // Authenticated link (rack/tims/link_auth.h): every TiMS packet on this network is
  // signed with, and must carry a valid MAC of, the keys in this file. "": none.
  std::string key_file;
};

struct ComponentInfo {
  Address address;
  std::string name;
  std::string impl;
};

struct HostInfo {
  std::string host;
  uint8_t system = 0;
  uint8_t host_id = 0;
  NodeRole role = NodeRole::kExecutor;
  int32_t pid = 0;
  int64_t origin = 0;
  Address executor;
  std::vector<ComponentInfo> components;
  int64_t last_seen_ns = 0;  // CLOCK_MONOTONIC of the receiver
  std::string network;       // where it was heard
};

struct TransportCounters {
  uint64_t packets_in = 0;
  uint64_t packets_out = 0;
  uint64_t messages_in = 0;  // whole TiMS messages received (after reassembly)
  uint64_t messages_out = 0;
  uint64_t malformed = 0;             // dropped: the sum of the four malformed_* kinds below
  uint64_t malformed_lcm = 0;         // not LCM: short, wrong magic, channel name unterminated or > 63 bytes
  uint64_t malformed_packet = 0;      // TIMS: not a tims_packet, bad chunk fields, bad header or length, zstd
  uint64_t malformed_announce = 0;    // TIMS_ANNOUNCE: does not decode (string length, count), fields out of range
  uint64_t malformed_discover = 0;    // TIMS_DISCOVER: does not decode, hops out of range
  uint64_t lcm_fragments = 0;         // LCM fragments (messages above 64 KB), refused: never RACK-RT's
  uint64_t hosts_refused = 0;         // announcements of new hosts refused: the table is full (256)
  uint64_t discovers_answered = 0;    // discover requests answered (at once, or after the interval)
  uint64_t discovers_suppressed = 0;  // discover requests that shared an answer due anyway (rate limit)
  uint64_t forged = 0;                // dropped: source address not owned by the sending host
  uint64_t not_for_us = 0;            // valid, for a mailbox not on this host
  uint64_t forwarded = 0;             // relayed to another network (routers)
  uint64_t not_available = 0;         // requests answered NOT_AVAILABLE by this authority
  uint64_t sequence_gaps = 0;         // packets missing between consecutive packet numbers
  uint64_t lost_messages = 0;         // chunked messages that never completed (reported)
  uint64_t publish_errors = 0;
  uint64_t delivery_failed = 0;  // local mailbox refused (full, too large)
  uint64_t hosts_expired = 0;
  uint64_t subscriptions_failed = 0;  // ERRORs sent to local consumers of lost hosts
  uint64_t streams_stopped = 0;       // local producers told to stop streaming to lost hosts
  uint64_t compressed_out = 0;
  uint64_t bytes_out = 0;       // TiMS bytes published (before compression)
  uint64_t wire_bytes_out = 0;  // payload bytes on the wire (after compression)
  uint64_t auth_failed = 0;     // dropped on a keyed network: unsigned, unknown key, bad MAC
  uint64_t replayed = 0;        // dropped on a keyed network: sequence seen, or outside the time window
};

struct LcmTransportConfig {
  // The networks to join. Empty: one robot network on `url`.
  std::vector<NetworkConfig> networks;
  std::string url = kDefaultLcmUrl;
  NodeRole role = NodeRole::kExecutor;
  uint32_t uplink_slots = 256;
  uint32_t uplink_slot_size = 64 * 1024;
  // Messages above uplink_slot_size go through a second uplink of a few large slots.
  uint32_t large_slots = 4;
  uint32_t max_message_bytes = 4 * 1024 * 1024 + 4096;  // largest message sent or accepted
  uint32_t reassembly_slots = 4;                        // large messages being received at once (per network)
  int64_t announce_period_ns = 1'000'000'000;           // 0: only at start, on change, on request
  int64_t expiry_ns = 3'000'000'000;                    // a host silent this long is gone
  int64_t reassembly_timeout_ns = 1'000'000'000;        // an incomplete message is lost after this
  // After start (which asks every host to announce itself) the discovery table needs
  // this long to fill before this host may answer NOT_AVAILABLE for others.
  int64_t warmup_ns = 500'000'000;
  // Discover requests are answered with an announcement at most once per this
  // interval per network; requests within it share the next answer (counted:
  // discovers_answered, discovers_suppressed).
  int64_t discover_answer_interval_ns = 100'000'000;
  // Keyed networks: how far a packet's time may be from ours (clocks synchronised by
  // PTP or chrony across hosts), and so how long a captured packet can be replayed
  // to a receiver that has not seen its sender.
  int64_t replay_window_ns = 5'000'000'000;
  // Scheduling of the receive threads (one per network): 0 normal scheduling (as
  // every other transport thread); 1..98 SCHED_FIFO at that priority, BELOW every
  // control task, so that a busy CPU (localisation, point clouds, a build) cannot starve a large
  // message's datagrams out of the socket buffer. Refused (no RT scheduling): a
  // warning, and the thread stays at normal scheduling.
  int receive_priority = 0;
  // Where warnings go (malformed packets, publish errors, expired hosts), rate-limited
  // by the transport. Default: stderr.
  std::function<void(const std::string&)> warn;
};

// For tools (rackctl, rack-gui): join `c.url` as one network signed and verified with
// `key_file` (the file a host file names as a network's key_file); an empty key file
// leaves the config unkeyed. Not RT (set-up).
inline void use_key_file(LcmTransportConfig& c, const std::string& tool_name, const std::string& key_file) {
  if (key_file.empty()) return;
  NetworkConfig n;
  n.name = tool_name;
  n.url = c.url;
  n.key_file = key_file;
  c.networks.push_back(n);
}

class LcmTransport {
 public:
  // Joins every network and makes the uplink mailboxes (their addresses are on the
  // tool system, never routed to). Throws std::runtime_error naming the URL on failure.
  LcmTransport(Router& router, LcmTransportConfig config);
  ~LcmTransport();
  LcmTransport(const LcmTransport&) = delete;
  LcmTransport& operator=(const LcmTransport&) = delete;

  void start();  // starts the threads, connects the router's uplinks, asks for discovery
  void stop();   // idempotent

  // What this host announces (executors and routers). Publishes at once when running.
  void set_announcement(HostInfo info);
  // Asks every host to announce itself.
  void request_discovery();
  // Blocks until the warm-up after start() has passed (the discovery table is full).
  void wait_until_warm() const;
  // Blocks until the uplinks hold at most `max_queued` messages not yet handed to LCM,
  // or `timeout_ns` passed (then false). Back-pressure for non-RT bulk senders (tools,
  // log players, bench_lcm) that must not overrun the uplink, which drops its oldest
  // message when full; RT tasks never wait here. Not RT-safe.
  bool wait_uplink(uint32_t max_queued, int64_t timeout_ns);
  // Live hosts heard from (announcements), one entry per host.
  [[nodiscard]] std::vector<HostInfo> hosts() const;

  [[nodiscard]] TransportCounters counters() const noexcept;
  // Handles one datagram in LCM's framing as if it had arrived on network `network`
  // (the receive path without the socket: fuzz harnesses drive it on a transport that
  // was never start()ed). Never throws; what it refuses is counted as on the socket.
  // Not RT-safe; not concurrently with a running receive thread of that network.
  void handle_datagram(const uint8_t* data, std::size_t size, std::size_t network = 0);
  // URL of the first network (tools print it).
  [[nodiscard]] const std::string& url() const noexcept;
  [[nodiscard]] int64_t origin() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rack::tims
