// LcmTransport: discovery: the announcements of every host (the table of who owns which
// address), discover requests and their coalesced answers, host expiry and restarts,
// and the subscriptions and streams that a lost host ends.
#include "lcm_transport_impl.h"

#include <unistd.h>

#include <algorithm>

#include "rack/rt/clock.h"

namespace rack::tims {

using namespace lcm_detail;

// Lock held. Whether this transport answers NOT_AVAILABLE for unknown mailboxes of
// `system` (see the header: exactly one authority per system).
bool LcmTransport::Impl::authoritative_locked(uint8_t system) const {
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
bool LcmTransport::Impl::same_addresses(const HostInfo& a, const HostInfo& b) {
  if (a.executor != b.executor || a.components.size() != b.components.size()) return false;
  for (std::size_t i = 0; i < a.components.size(); ++i) {
    if (a.components[i].address != b.components[i].address) return false;
  }
  return true;
}

void LcmTransport::Impl::rebuild_owners_locked() {
  owners.clear();
  for (const auto& [o, e] : hosts) {
    owners[e.info.executor.component().raw()] = o;
    for (const auto& c : e.info.components) owners[c.address.component().raw()] = o;
  }
}

// Lock held. Sends an ERROR, in the producer's name, to every local consumer of a
// component of `lost` (as the producer would when going OFF) and forgets them.
void LcmTransport::Impl::fail_subscriptions_locked(const HostInfo& lost, const std::string& why) {
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

void LcmTransport::Impl::expire_hosts() {
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
      return "TiMS/LCM: " + std::to_string(more) + " more host(s) expired at the same time (counted in hosts_expired)";
    });
  }
}

void LcmTransport::Impl::on_announce(Network& n, const uint8_t* d, std::size_t size, const std::string&) {
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
             std::to_string(a.host_id) + ", role " + std::to_string(a.role) + ", hops " + std::to_string(a.hops) + ")";
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
void LcmTransport::Impl::on_discover(Network& n, const uint8_t* d, std::size_t size, const std::string&) {
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
void LcmTransport::Impl::answer_pending_discovers() {
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
void LcmTransport::Impl::publish_announcement(Network* only) {
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

void LcmTransport::Impl::forget_subscription_locked(uint32_t producer, uint32_t listener) {
  subscriptions.erase(
      std::remove_if(subscriptions.begin(), subscriptions.end(),
                     [&](const Subscription& s) { return s.producer == producer && s.listener == listener; }),
      subscriptions.end());
}

// Remembers GET_CONT_DATA/STOP_CONT_DATA that leave this host, so that local
// consumers learn of a lost producer host. Body layouts: rack::wire::ContDataRequest
// (int64 period, uint32 mailbox) and StopContDataRequest (uint32 mailbox), native.
void LcmTransport::Impl::track_subscription_locked(const MessageHeader& h, std::span<const std::byte> body) {
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

std::vector<HostInfo> LcmTransport::hosts() const {
  std::lock_guard lock(impl_->table_mutex);
  std::vector<HostInfo> out;
  for (const auto& [key, e] : impl_->hosts) out.push_back(e.info);
  return out;
}

}  // namespace rack::tims
