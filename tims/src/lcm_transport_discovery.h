// Who is on the networks (internal to tims): the table of live hosts from their
// announcements (who owns which address) and the rules built on it (which host answers
// NOT_AVAILABLE for a system, which source is forged), this host's own announcement
// and the pace of its answers to discover requests, host expiry and restarts, and the
// data flows to and from other hosts that a lost host ends (RemoteSubscriptions). It
// decides; the transport publishes and forwards (lcm_transport_impl.h).
//
// Real-time contract: nothing here is RT-safe (the transport's non-RT threads).
// Thread-safety: any thread of the transport; the table under one mutex, the
// announcement under another (never both at once; RemoteSubscriptions sends to local
// mailboxes under the table's).
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "lcm_transport_stats.h"
#include "lcm_transport_subscriptions.h"
#include "rack/rt/clock.h"
#include "rack/tims/router.h"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/host_announce.hpp"

namespace rack::tims {

class Discovery {
 public:
  // Hosts kept in the table at once: a flood of announcements with made-up origins is
  // refused (counted: hosts_refused) instead of growing the table (and the work of
  // every announcement) without bound. Far above a fleet's size.
  static constexpr std::size_t kMaxHosts = 256;

  // `config`: the transport's (role, timing), kept by reference; `networks`: how many
  // networks answer discover requests; `control`: the transport's own mailbox (the
  // source of its STOP_CONT_DATA).
  Discovery(Router& router, const LcmTransportConfig& config, int64_t origin, std::size_t networks, Address control,
            TransportStats& stats, lcm_rx::RateLimitedWarn& warn);

  // The warm-up (LcmTransportConfig::warmup_ns) starts now: until it has passed, this
  // host answers for nobody. Before the transport's threads start.
  void start(int64_t now_ns) noexcept { started_ns_ = now_ns; }
  [[nodiscard]] bool warm() const;
  [[nodiscard]] uint8_t own_system() const noexcept { return own_system_.load(std::memory_order_relaxed); }

  // A component (or executor) address that a live host announced.
  [[nodiscard]] bool known(Address a) const;
  // A whole message heard from `origin`: whether its source is forged (an address of
  // ours, or of a component another host announced), and whether this host answers
  // NOT_AVAILABLE for its unknown destination. An ERROR ends the subscription it
  // answers.
  struct Incoming {
    bool forged = false;
    bool answer_not_available = false;
  };
  Incoming incoming(const MessageHeader& h, int64_t origin);
  // A message about to leave this host (sender threads): remembered when it starts or
  // ends a subscription or streams data; answered NOT_AVAILABLE (a request) or dropped
  // (anything else) when nobody announced its destination and this host is the
  // authority for its system.
  struct Outgoing {
    bool answer_not_available = false;
    bool drop = false;
  };
  Outgoing outgoing(const MessageHeader& h, std::span<const std::byte> body);

  // An announcement heard on network `log`: decoded and checked (refusals through
  // `log`), taken into the table (restarts, id conflicts and a full table said).
  // True when `a` is another host's valid announcement that routers pass on.
  bool take_announcement(NetworkLog& log, const uint8_t* d, std::size_t size, rack_lcm::host_announce& a);
  // A discover request heard on network `network`: decoded and checked. Answered at
  // once (answer_now: publish the announcement there), or later (the interval since
  // the last answer has not passed; answer_due() says when), or shared with an answer
  // due anyway (suppressed). pass_on: routers pass it on (not coalesced).
  struct DiscoverAnswer {
    bool answer_now = false;
    bool pass_on = false;
  };
  DiscoverAnswer take_discover(std::size_t network, NetworkLog& log, const uint8_t* d, std::size_t size,
                               rack_lcm::discover_request& r);
  // Whether a coalesced answer on `network` is due now (maintenance thread).
  [[nodiscard]] bool answer_due(std::size_t network);

  // What this host announces (set_announcement); nothing is published here.
  void set_announcement(const HostInfo& info);
  // Calls publish(network, announcement) for network `only` (or every network when
  // `only` is kAll) under the announcement's lock, once one was set; each such network
  // counts as answered now.
  static constexpr std::size_t kAll = SIZE_MAX;
  template <typename Publish>
  void announce(std::size_t only, Publish publish) {
    std::lock_guard lock(announce_mutex_);
    if (!have_announcement_) return;
    announcement_.time_ns = rt::host_time_ns();
    const int64_t now = rt::monotonic_ns();
    for (std::size_t i = 0; i < answering_.size(); ++i) {
      if (only != kAll && i != only) continue;
      answering_[i].last_announce_ns = now;  // answers every discover request heard so far
      answering_[i].pending = false;
      publish(i, announcement_);
    }
  }

  // Hosts silent for longer than expiry_ns are taken off the table (maintenance
  // thread); their subscriptions and streams are ended, each said.
  void expire_hosts();
  [[nodiscard]] std::vector<HostInfo> hosts() const;

 private:
  struct HostEntry {
    HostInfo info;
    int64_t first_seen_ns = 0;  // when its origin was first heard (its warm-up began)
  };
  // Discover answers per network: when this host last announced there, and whether a
  // coalesced request waits for its answer.
  struct Answering {
    int64_t last_announce_ns = INT64_MIN / 2;
    bool pending = false;
  };

  [[nodiscard]] NodeRole role() const noexcept { return config_.role; }
  bool known_locked(Address a) const { return owners_.count(a.component().raw()) != 0; }
  bool authoritative_locked(uint8_t system) const;
  static bool same_addresses(const HostInfo& a, const HostInfo& b);
  void rebuild_owners_locked();

  Router& router_;
  const LcmTransportConfig& config_;
  const int64_t origin_;
  TransportStats& stats_;
  lcm_rx::RateLimitedWarn& warn_;
  int64_t started_ns_ = 0;
  std::atomic<uint8_t> own_system_{0};

  // The table and the flows across hosts (non-RT threads only).
  mutable std::mutex table_mutex_;
  std::map<int64_t, HostEntry> hosts_;            // by origin
  std::unordered_map<uint32_t, int64_t> owners_;  // component address -> origin
  RemoteSubscriptions flows_;
  std::set<int64_t> retired_;  // origins of hosts taken for restarted (bounded)
  bool have_own_id_ = false;
  uint8_t own_host_id_ = 0;

  std::mutex announce_mutex_;
  bool have_announcement_ = false;
  rack_lcm::host_announce announcement_;
  std::vector<Answering> answering_;  // per network
};

}  // namespace rack::tims
