// Discovery: the announcements of every host (the table of who owns which address),
// discover requests and their coalesced answers, host expiry and restarts
// (lcm_transport_discovery.h).
#include "lcm_transport_discovery.h"

#include <algorithm>

#include "lcm_transport_packet.h"
#include "rack/rt/clock.h"

namespace rack::tims {

using namespace lcm_detail;

Discovery::Discovery(Router& router, const LcmTransportConfig& config, int64_t origin, std::size_t networks,
                     Address control, TransportStats& stats, lcm_rx::RateLimitedWarn& warn)
    : router_(router),
      config_(config),
      origin_(origin),
      stats_(stats),
      warn_(warn),
      own_system_(router.system()),
      flows_(router, control, stats),
      answering_(networks) {}

bool Discovery::warm() const { return rt::monotonic_ns() - started_ns_ >= config_.warmup_ns; }

bool Discovery::known(Address a) const {
  std::lock_guard lock(table_mutex_);
  return known_locked(a);
}

// Lock held. Whether this transport answers NOT_AVAILABLE for unknown mailboxes of
// `system` (rack/tims/lcm_transport.h: exactly one authority per system).
bool Discovery::authoritative_locked(uint8_t system) const {
  if (system == kToolSystem || role() == NodeRole::kTool || !warm()) return false;
  bool system_router = false, lower_executor = false, lower_top_router = false;
  const int64_t now = rt::monotonic_ns();
  const uint8_t own_system = own_system_.load(std::memory_order_relaxed);
  for (const auto& [o, e] : hosts_) {
    // Several top routers share a fleet (no single point of failure): the live one
    // with the lowest host id answers, the others stand by until it expires. One
    // heard for less than a warm-up is not answering yet (it has just started): this
    // one goes on answering meanwhile (both may answer for a moment; the requester
    // takes the first reply and drops the second as stale).
    if (e.info.role == NodeRole::kTopRouter && e.info.host_id < own_host_id_ &&
        now - e.first_seen_ns >= config_.warmup_ns) {
      lower_top_router = true;
    }
    if (e.info.system != system) continue;
    if (e.info.role == NodeRole::kSystemRouter) system_router = true;
    if (e.info.role == NodeRole::kExecutor && e.info.host_id < own_host_id_) lower_executor = true;
  }
  switch (role()) {
    case NodeRole::kTopRouter: return !system_router && !lower_top_router;
    case NodeRole::kSystemRouter: return system == own_system;
    case NodeRole::kExecutor: return system == own_system && !system_router && !lower_executor;
    case NodeRole::kTool: return false;
  }
  return false;
}

Discovery::Incoming Discovery::incoming(const MessageHeader& h, int64_t origin) {
  Incoming r;
  r.forged = router_.find(h.source()) != nullptr;
  std::lock_guard lock(table_mutex_);
  if (!r.forged && h.source().system() != kToolSystem) {
    const auto it = owners_.find(h.source().component().raw());
    r.forged = it != owners_.end() && it->second != origin;
  }
  if (!known_locked(h.destination()) && h.is_request()) {
    r.answer_not_available = authoritative_locked(h.destination().system());
  }
  if (h.type == msg::kError) flows_.forget(h.source().component().raw(), h.dest);
  return r;
}

Discovery::Outgoing Discovery::outgoing(const MessageHeader& h, std::span<const std::byte> body) {
  Outgoing r;
  std::lock_guard lock(table_mutex_);
  flows_.track(h, body);
  if (h.destination().system() != kToolSystem && !known_locked(h.destination()) &&
      authoritative_locked(h.destination().system())) {
    (h.is_request() ? r.answer_not_available : r.drop) = true;
  }
  return r;
}

// Whether two announcements of a host name the same executor and component addresses
// (what `owners_` maps).
bool Discovery::same_addresses(const HostInfo& a, const HostInfo& b) {
  if (a.executor != b.executor || a.components.size() != b.components.size()) return false;
  for (std::size_t i = 0; i < a.components.size(); ++i) {
    if (a.components[i].address != b.components[i].address) return false;
  }
  return true;
}

void Discovery::rebuild_owners_locked() {
  owners_.clear();
  for (const auto& [o, e] : hosts_) {
    owners_[e.info.executor.component().raw()] = o;
    for (const auto& c : e.info.components) owners_[c.address.component().raw()] = o;
  }
}

void Discovery::expire_hosts() {
  std::vector<std::pair<std::string, std::string>> lines;  // rate-limit key (the host), text
  {
    std::lock_guard lock(table_mutex_);
    const int64_t now = rt::monotonic_ns();
    bool changed = false;
    for (auto it = hosts_.begin(); it != hosts_.end();) {
      const int64_t silent = now - it->second.info.last_seen_ns;
      if (silent <= config_.expiry_ns) {
        ++it;
        continue;
      }
      const HostInfo& info = it->second.info;
      lines.emplace_back(
          "expired " + info.host + " " + std::to_string(info.system) + "/" + std::to_string(info.host_id),
          "TiMS/LCM: host '" + info.host + "' (system " + std::to_string(info.system) + ", host id " +
              std::to_string(info.host_id) + ", pid " + std::to_string(info.pid) + ", " + describe(info.role) +
              ") expired: no announcement for " + std::to_string(silent / rt::kNsPerMs) + " ms");
      flows_.end(info, "no announcement for " + std::to_string(silent / rt::kNsPerMs) + " ms");
      bump(stats_.hosts_expired);
      it = hosts_.erase(it);
      changed = true;
    }
    if (changed) rebuild_owners_locked();
  }
  // Each host at most once a second (one that comes and goes is counted into its next
  // line), and at most kMaxExpiredLines lines per pass: a fleet that drops off the
  // network at once (a switch restarts) is one line more, not hundreds.
  constexpr std::size_t kMaxExpiredLines = 8;
  for (std::size_t i = 0; i < lines.size() && i < kMaxExpiredLines; ++i) {
    warn_(lines[i].first, [&] { return lines[i].second; });
  }
  if (lines.size() > kMaxExpiredLines) {
    const std::size_t more = lines.size() - kMaxExpiredLines;
    warn_("expired more", [&] {
      return "TiMS/LCM: " + std::to_string(more) + " more host(s) expired at the same time (counted in hosts_expired)";
    });
  }
}

bool Discovery::take_announcement(NetworkLog& log, const uint8_t* d, std::size_t size, rack_lcm::host_announce& a) {
  // lcm_wire.h: every string and the component count checked before anything is
  // allocated (lcm-gen's decoder throws on a string length of 0).
  std::string why;
  if (wire_lcm::decode(d, size, a, why) < 0) {
    log.reject("announce", [&] { return "announcement of " + std::to_string(size) + " bytes: " + why; });
    return false;
  }
  if (a.system < 0 || a.system > 254 || a.host_id < 0 || a.host_id > 255 || a.role < 0 || a.role > 2 || a.hops < 0 ||
      a.hops > kMaxHops) {
    log.reject("announce", [&] {
      return "announcement with fields out of range (system " + std::to_string(a.system) + ", host_id " +
             std::to_string(a.host_id) + ", role " + std::to_string(a.role) + ", hops " + std::to_string(a.hops) + ")";
    });
    return false;
  }
  // Names go to terminals (rackctl list, hosts) and browsers (rack-gui): a host file
  // cannot hold control characters, so an announcement that does is refused.
  bool has_control = wire_lcm::has_control(a.host);
  for (const auto& c : a.components) {
    has_control = has_control || wire_lcm::has_control(c.name) || wire_lcm::has_control(c.impl);
  }
  if (has_control) {
    log.reject("announce", [&] { return std::string("announcement with a control character in a name"); });
    return false;
  }
  if (a.origin == origin_ || a.relay == origin_) return false;  // our own
  HostInfo info;
  info.host = a.host;
  info.system = static_cast<uint8_t>(a.system);
  info.host_id = static_cast<uint8_t>(a.host_id);
  info.role = static_cast<NodeRole>(a.role);
  info.pid = a.pid;
  info.origin = a.origin;
  info.executor = Address(static_cast<uint32_t>(a.executor));
  info.last_seen_ns = rt::monotonic_ns();
  info.network = log.name();
  for (const auto& c : a.components) {
    info.components.push_back({Address(static_cast<uint32_t>(c.address)), c.name, c.impl});
  }
  std::string replaced, conflict;
  bool full = false, owners_changed = false;
  {
    std::lock_guard lock(table_mutex_);
    const uint8_t own_system = own_system_.load(std::memory_order_relaxed);
    const auto same_id = [&](const HostInfo& h) {
      return h.system == info.system && h.host_id == info.host_id && h.role == info.role;
    };
    if (have_own_id_ && role() != NodeRole::kTool && info.system == own_system && info.host_id == own_host_id_ &&
        info.role == role()) {
      conflict = "TiMS/LCM: host '" + info.host + "' (pid " + std::to_string(info.pid) +
                 ") announces this host's own system " + std::to_string(own_system) + " and host id " +
                 std::to_string(own_host_id_) + ": give every computer of a robot its own host_id";
    }
    // Same host (system and host id), new origin: it restarted. What we knew of the
    // old one is gone now, not only after the expiry. Unless the "old" one is still
    // alive: an origin we retired that announces again, or that a retired one
    // replaced, means two hosts share the id (a configuration error, reported).
    for (auto it = hosts_.begin(); it != hosts_.end();) {
      const HostInfo& old = it->second.info;
      if (it->first == a.origin || !same_id(old)) {
        ++it;
        continue;
      }
      if (retired_.count(a.origin) != 0 || retired_.count(it->first) != 0) {
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
      if (retired_.size() > 1024) retired_.clear();
      retired_.insert(it->first);
      flows_.end(old, "restarted");
      bump(stats_.hosts_expired);
      it = hosts_.erase(it);
      owners_changed = true;
    }
    if (hosts_.size() >= kMaxHosts && hosts_.count(a.origin) == 0) {
      bump(stats_.hosts_refused);
      full = true;
    } else {
      auto& e = hosts_[a.origin];
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
    log.warn("hosts full " + log.name(), [&] {
      return "TiMS/LCM: refused an announcement of host '" + a.host + "' (origin " + origin_text(a.origin) +
             ") on network '" + log.name() + "': " + std::to_string(kMaxHosts) +
             " hosts known already (a flood of made-up hosts?)";
    });
    return false;
  }
  if (!replaced.empty()) warn_("restart " + replaced, [&] { return replaced; });
  if (!conflict.empty()) {
    warn_("conflict " + std::to_string(a.system) + "/" + std::to_string(a.host_id), [&] { return conflict; });
  }
  return true;
}

// A discover request is answered with this host's announcement on the network it
// came from, at most once per discover_answer_interval_ns there: requests that come
// while an answer is due or was just sent share it (coalesced, counted as
// suppressed), so a flood of requests costs one announcement per interval, not one
// each. A periodic announcement answers them too. Routers pass on only requests
// that were not coalesced.
Discovery::DiscoverAnswer Discovery::take_discover(std::size_t network, NetworkLog& log, const uint8_t* d,
                                                   std::size_t size, rack_lcm::discover_request& r) {
  std::string why;
  if (wire_lcm::decode(d, size, r, why) < 0) {
    log.reject("discover", [&] { return "discover request of " + std::to_string(size) + " bytes: " + why; });
    return {};
  }
  if (r.hops < 0 || r.hops > kMaxHops) {
    log.reject("discover", [&] { return "discover request with " + std::to_string(r.hops) + " hops"; });
    return {};
  }
  if (r.origin == origin_ || r.relay == origin_) return {};
  DiscoverAnswer answer;
  std::lock_guard lock(announce_mutex_);
  if (have_announcement_) {
    Answering& n = answering_[network];
    if (n.pending || rt::monotonic_ns() - n.last_announce_ns < config_.discover_answer_interval_ns) {
      if (n.pending) {
        bump(stats_.discovers_suppressed);
        return {};
      }
      n.pending = true;  // the maintenance thread answers when the interval has passed
    } else {
      answer.answer_now = true;
    }
    bump(stats_.discovers_answered);
  }
  answer.pass_on = true;
  return answer;
}

bool Discovery::answer_due(std::size_t network) {
  std::lock_guard lock(announce_mutex_);
  const Answering& n = answering_[network];
  return n.pending && rt::monotonic_ns() - n.last_announce_ns >= config_.discover_answer_interval_ns;
}

void Discovery::set_announcement(const HostInfo& info) {
  {
    std::lock_guard lock(announce_mutex_);
    auto& a = announcement_;
    a.origin = origin_;
    a.relay = 0;
    a.hops = 0;
    a.role = static_cast<int8_t>(config_.role == NodeRole::kTool ? NodeRole::kExecutor : config_.role);
    a.period_ns = config_.announce_period_ns;
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
    have_announcement_ = true;
  }
  std::lock_guard lock(table_mutex_);
  own_system_.store(info.system, std::memory_order_relaxed);
  own_host_id_ = info.host_id;
  have_own_id_ = true;
}

std::vector<HostInfo> Discovery::hosts() const {
  std::lock_guard lock(table_mutex_);
  std::vector<HostInfo> out;
  for (const auto& [key, e] : hosts_) out.push_back(e.info);
  return out;
}

}  // namespace rack::tims
