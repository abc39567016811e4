// Host files: the tims: section (role, discovery timing, message limits, networks and
// their keys) and gdos: (the log service).
#include "host_loader.h"

#include <cmath>

#include "rack/tims/link_auth.h"

namespace rack {

void NetworkReader::read_gdos(const YAML::Node& g, GdosSettings& out) {
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
void NetworkReader::load_tims(const YAML::Node& t, HostSettings& hs, bool have_lcm_url) {
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
      nc.key_file = resolve_path(base_dir_, nc.key_file);
      if (nc.key_file.empty()) {
        error(n["key_file"].Mark(), "'key_file' must not be empty (leave it out for an unauthenticated network)");
      } else if (!options_.open_files) {
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

}  // namespace rack
