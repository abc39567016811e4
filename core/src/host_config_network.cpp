// Host files: the tims: section (role, discovery timing, message limits, networks and
// their keys), gdos: (the log service) and access: (who may send what to whom).
#include "host_loader.h"

#include <cmath>

#include "rack/tims/link_auth.h"

namespace rack {

void HostLoader::read_gdos(const YAML::Node& g, GdosSettings& out) {
  if (!g.IsMap()) {
    error(g.Mark(), "'gdos' must be a map (level, stderr, ring, drain_ms, lcm, lcm_url, channel)");
    return;
  }
  check_keys(g, {"level", "stderr", "ring", "drain_ms", "lcm", "lcm_url", "channel"}, "gdos");
  std::string text;
  if (get(g, "level", text, std::string("a GDOS level (") + gdos::kLevelNames + ")")) {
    if (const auto l = gdos::parse_level(text)) out.level = *l;
    else error(g["level"].Mark(), "'level' must be one of " + std::string(gdos::kLevelNames) + ", got '" + text + "'");
  }
  if (get(g, "stderr", text, "always, auto or never")) {
    if (text == "always") out.to_stderr = GdosSettings::Stderr::kAlways;
    else if (text == "auto") out.to_stderr = GdosSettings::Stderr::kAuto;
    else if (text == "never") out.to_stderr = GdosSettings::Stderr::kNever;
    else error(g["stderr"].Mark(), "'stderr' must be always, auto or never, got '" + text + "'");
  }
  int64_t v = 0;
  if (get_int_range(g, "ring", 2, 65536, v, "a record count 2..65536")) out.ring = static_cast<uint32_t>(v);
  get_positive_ms(g, "drain_ms", out.drain_ns);
  get(g, "lcm", out.lcm, "true or false");
  if (get(g, "lcm_url", out.lcm_url, "an LCM URL")) check_url(g, "lcm_url", out.lcm_url);
  if (get(g, "channel", out.channel, "an LCM channel name") && !valid_name(out.channel, kMaxChannelLength, true)) {
    error(g["channel"].Mark(), "'channel' '" + printable(out.channel) + "' must be 1.." +
                                   std::to_string(kMaxChannelLength) + " letters, digits, '.', '_' or '-'");
  }
}

// The `tims:` section: role, discovery timing, message limits, networks.
void HostLoader::load_tims(const YAML::Node& t, HostSettings& hs, bool have_lcm_url) {
  if (!t.IsMap()) {
    error(t.Mark(), "'tims' must be a map (role, announce_ms, expiry_ms, max_message_kib, large_slots, networks)");
    return;
  }
  check_keys(t,
             {"role", "announce_ms", "expiry_ms", "max_message_kib", "large_slots", "networks", "replay_window_ms",
              "receive_priority"},
             "'tims'");
  if (int64_t w = 0; get_positive_ms(t, "replay_window_ms", w)) hs.replay_window_ns = w;
  std::string role;
  if (get(t, "role", role, "executor, system_router or top_router")) {
    if (role == "executor") hs.role = tims::NodeRole::kExecutor;
    else if (role == "system_router") hs.role = tims::NodeRole::kSystemRouter;
    else if (role == "top_router") hs.role = tims::NodeRole::kTopRouter;
    else error(t["role"].Mark(), "'role' must be executor, system_router or top_router, got '" + role + "'");
  }
  int64_t ns = 0;
  if (get_positive_ms(t, "announce_ms", ns)) hs.announce_period_ns = ns;
  if (get_positive_ms(t, "expiry_ms", ns)) hs.expiry_ns = ns;
  // Another host counts this one gone after expiry_ms without an announcement: one
  // lost announcement (a datagram) must not expire it, so at least two periods.
  if ((t["expiry_ms"] || t["announce_ms"]) && hs.expiry_ns < 2 * hs.announce_period_ns) {
    error(t[t["expiry_ms"] ? "expiry_ms" : "announce_ms"].Mark(),
          "'expiry_ms' (" + std::to_string(hs.expiry_ns / 1'000'000) + " ms) must be at least twice 'announce_ms' (" +
              std::to_string(hs.announce_period_ns / 1'000'000) +
              " ms): longer than 'announce_ms' by one lost announcement, or hosts expire between announcements");
  }
  int64_t v = 0;
  if (get_int_range(t, "max_message_kib", 64, 256 * 1024, v, "a size in KiB")) {
    hs.max_message_bytes = static_cast<uint32_t>(v * 1024 + 4096);
  }
  if (get_int_range(t, "large_slots", 1, 64, v, "a number of slots")) hs.large_slots = static_cast<uint32_t>(v);
  if (get_int_range(t, "receive_priority", 0, 98, v, "0 (normal scheduling) or a SCHED_FIFO priority 1..98")) {
    hs.receive_priority = static_cast<int>(v);
  }
  const YAML::Node nets = t["networks"];
  if (!nets) return;
  if (!nets.IsSequence() || nets.size() == 0) {
    error(nets.Mark(), "'networks' must be a non-empty list of {name, url, scope, compress}");
    return;
  }
  if (have_lcm_url) error(nets.Mark(), "give either 'lcm_url' or 'tims: networks:', not both");
  std::set<std::string> names;
  for (const auto& n : nets) {
    if (!n.IsMap()) {
      error(n.Mark(), "a network is a map {name, url, scope, compress, compress_min_kib}");
      continue;
    }
    check_keys(n, {"name", "url", "scope", "compress", "compress_min_kib", "key_file"}, "a network");
    tims::NetworkConfig nc;
    get(n, "name", nc.name, "a name");
    if (!n["url"]) error(n.Mark(), "network '" + nc.name + "' has no 'url'");
    if (get(n, "url", nc.url, "an LCM URL such as udpm://239.255.76.67:7667?ttl=1")) check_url(n, "url", nc.url);
    if (n["name"] && !valid_name(nc.name, kMaxNameLength, false)) {
      error(n["name"].Mark(), "network name '" + printable(nc.name) + "' must be 1.." + std::to_string(kMaxNameLength) +
                                  " letters, digits, '_' or '-'");
    }
    if (!names.insert(nc.name).second) error(n.Mark(), "two networks named '" + nc.name + "'");
    std::string scope = "robot";
    if (get(n, "scope", scope, "robot or fleet")) {
      if (scope == "robot") nc.scope = tims::NetworkScope::kRobot;
      else if (scope == "fleet") nc.scope = tims::NetworkScope::kFleet;
      else error(n["scope"].Mark(), "'scope' must be robot or fleet, got '" + scope + "'");
    }
    std::string compress = "none";
    if (get(n, "compress", compress, "none or zstd")) {
      if (compress == "none") nc.compression = tims::Compression::kNone;
      else if (compress == "zstd") nc.compression = tims::Compression::kZstd;
      else error(n["compress"].Mark(), "'compress' must be none or zstd, got '" + compress + "'");
    }
    if (get_int_range(n, "compress_min_kib", 0, 1024 * 1024, v, "a size in KiB")) {
      nc.compress_min_bytes = static_cast<uint32_t>(v * 1024);
    }
    // The key itself never is in the host file: only the path of a file that group
    // and others cannot read. Checked here so that --check reports it too.
    if (get(n, "key_file", nc.key_file, "the path of a key file")) {
      nc.key_file = resolve_path(base_dir, nc.key_file);
      if (nc.key_file.empty()) {
        error(n["key_file"].Mark(), "'key_file' must not be empty (leave it out for an unauthenticated network)");
      } else if (!options.open_files) {
        // the path only
      } else if (const auto kf = tims::load_key_file(nc.key_file); !kf.error.empty()) {
        error(n["key_file"].Mark(), kf.error);
      }
    }
    hs.networks.push_back(nc);
  }
  if (hs.role == tims::NodeRole::kSystemRouter) {
    bool robot = false, fleet = false;
    for (const auto& nc : hs.networks) (nc.scope == tims::NetworkScope::kRobot ? robot : fleet) = true;
    if (!robot || !fleet) {
      error(nets.Mark(),
            "a system_router bridges its robot's network and the fleet network: list one of "
            "each (scope: robot, scope: fleet)");
    }
  }
}

// A `to`/`from` entry: a component name of this host file, an address pattern
// (rack/tims/access.h: parse_address_mask), or (from only) local / network.
bool HostLoader::read_access_addresses(const YAML::Node& node, const char* key, std::vector<tims::AddressMask>& out,
                                       tims::AccessRuleConfig* rule) {
  const YAML::Node n = node[key];
  if (!n) return false;
  std::vector<YAML::Node> items;
  if (n.IsScalar()) items.push_back(n);
  else if (n.IsSequence())
    for (const auto& i : n) items.push_back(i);
  else {
    error(n.Mark(), std::string("'") + key + "' must be a name, an address pattern or a list of them");
    return false;
  }
  for (const auto& i : items) {
    if (!i.IsScalar()) {
      error(i.Mark(), std::string("an entry of '") + key + "' is a name or an address pattern");
      continue;
    }
    const std::string text = i.Scalar();
    if (rule != nullptr && text == "local") {
      rule->from_local = true;
      continue;
    }
    if (rule != nullptr && text == "network") {
      rule->from_network = true;
      continue;
    }
    if (const auto it = component_addresses.find(text); it != component_addresses.end()) {
      out.push_back({it->second.component().raw(), 0xFFFFFF00u});  // all its mailboxes
      continue;
    }
    if (const auto m = tims::parse_address_mask(text)) {
      out.push_back(*m);
      continue;
    }
    error(i.Mark(), "'" + text + "' in '" + key + "' is neither a component of this host file nor an address " +
                        "pattern (Class(sys/inst), Class(sys/*), *(sys/*), 0xVALUE/0xMASK" +
                        (rule != nullptr ? std::string(", local, network") : std::string()) + ")");
  }
  return true;
}

// The `access:` section (configs/access_control.yaml explains every key).
void HostLoader::read_access(const YAML::Node& a, LoadedHost& host) {
  HostSettings& hs = host.settings;
  if (!a.IsMap()) {
    error(a.Mark(), "'access' must be a map (default, log_ms, sources, rules)");
    return;
  }
  hs.access_configured = true;
  check_keys(a, {"default", "log_ms", "sources", "rules"}, "'access'");
  std::string text;
  if (get(a, "default", text, "open or closed")) {
    if (text == "open") hs.access.default_policy = tims::AccessDefault::kOpen;
    else if (text == "closed") hs.access.default_policy = tims::AccessDefault::kClosed;
    else error(a["default"].Mark(), "'default' must be open or closed, got '" + text + "'");
  }
  get_positive_ms(a, "log_ms", hs.access_log_ns);
  int64_t v = 0;
  if (get_int_range(a, "sources", 16, 1 << 20, v, "a number of per-source buckets")) {
    hs.access.sources = static_cast<uint32_t>(v);
  }
  const YAML::Node rules = a["rules"];
  if (!rules) return;
  if (!rules.IsSequence()) {
    error(rules.Mark(), "'rules' must be a list of {name, to, from, types, max_priority, rate, ...}");
    return;
  }
  // One rule is rackd's own (its executor's commands are always allowed).
  if (rules.size() > tims::AccessControl::kMaxRules - 1) {
    error(rules.Mark(), "at most " + std::to_string(tims::AccessControl::kMaxRules - 1) + " rules");
    return;
  }
  std::set<std::string> names;
  for (const auto& r : rules) {
    if (!r.IsMap()) {
      error(r.Mark(), "a rule is a map {name, to, from, types, max_priority, rate, burst, bandwidth_kib, burst_kib}");
      continue;
    }
    check_keys(r, {"name", "to", "from", "types", "max_priority", "rate", "burst", "bandwidth_kib", "burst_kib"},
               "an access rule");
    tims::AccessRuleConfig rc;
    get(r, "name", rc.name, "a name");
    if (rc.name.empty()) rc.name = "rule " + std::to_string(hs.access.rules.size() + 1);
    if (rc.name.size() >= tims::AccessControl::kNameLen) {
      error(r["name"].Mark(), "rule name '" + rc.name + "' is longer than " +
                                  std::to_string(tims::AccessControl::kNameLen - 1) + " characters");
    }
    if (rc.name == "rackd") error(r["name"].Mark(), "the rule name 'rackd' is rackd's own (its executor's commands)");
    if (!names.insert(rc.name).second) error(r.Mark(), "two access rules named '" + rc.name + "'");
    if (!read_access_addresses(r, "to", rc.to, nullptr)) {
      if (!r["to"]) error(r.Mark(), "access rule '" + rc.name + "' has no 'to' (the components it protects)");
    }
    read_access_addresses(r, "from", rc.from, &rc);
    for (const char* k : {"to", "from"}) {
      if (r[k] && r[k].IsSequence() && r[k].size() > tims::AccessControl::kMaxMasks) {
        error(r[k].Mark(),
              std::string("at most ") + std::to_string(tims::AccessControl::kMaxMasks) + " entries in '" + k + "'");
      }
    }
    if (const YAML::Node t = r["types"]) {
      rc.any_type = false;
      std::vector<YAML::Node> items;
      if (t.IsScalar()) items.push_back(t);
      else if (t.IsSequence())
        for (const auto& i : t) items.push_back(i);
      else error(t.Mark(), "'types' must be a list of message types (names such as get_status, or numbers)");
      for (const auto& i : items) {
        int8_t type = 0;
        if (!i.IsScalar() || !tims::parse_message_type(i.Scalar(), type)) {
          error(i.Mark(),
                "'" + (i.IsScalar() ? i.Scalar() : std::string("?")) +
                    "' is not a message type (on, off, get_status, get_data, get_cont_data, "
                    "stop_cont_data, get_next_data, get_param, set_param, get_stats, get_latency, a reply name "
                    "such as data, or a number -128..127)");
          continue;
        }
        rc.types.set(static_cast<std::size_t>(type + 128));
        if (type <= 0) rc.restricts_replies = true;
      }
    }
    if (get_int_range(r, "max_priority", 0, 255, v, "a priority 0..255")) rc.max_priority = static_cast<int>(v);
    const auto positive = [&](const char* key, double& out, double scale) {
      double d = 0;
      if (!get(r, key, d, "a positive number")) return;
      if (!(d > 0) || !std::isfinite(d)) {
        error(r[key].Mark(), std::string("'") + key + "' must be positive, got " + r[key].Scalar());
        return;
      }
      out = d * scale;
    };
    positive("rate", rc.rate, 1.0);
    positive("burst", rc.burst, 1.0);
    positive("bandwidth_kib", rc.bandwidth, 1024.0);
    positive("burst_kib", rc.burst_bytes, 1024.0);
    if (r["burst"] && !r["rate"]) error(r["burst"].Mark(), "'burst' without 'rate'");
    if (r["burst_kib"] && !r["bandwidth_kib"]) error(r["burst_kib"].Mark(), "'burst_kib' without 'bandwidth_kib'");
    hs.access.rules.push_back(std::move(rc));
  }
}

}  // namespace rack
