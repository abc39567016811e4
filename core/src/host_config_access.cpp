// Host files: the access: section (who may send what to whom; configs/access_control.yaml
// explains every key): rules, and the component names and address patterns they name.
#include "host_loader.h"

#include <cmath>

namespace rack {

// A `to`/`from` entry: a component name of this host file, an address pattern
// (rack/tims/access.h: parse_address_mask), or (from only) local / network.
bool AccessReader::read_access_addresses(const YAML::Node& node, const char* key, std::vector<tims::AddressMask>& out,
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
    if (const auto it = component_addresses_.find(text); it != component_addresses_.end()) {
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
void AccessReader::read_access(const YAML::Node& a, LoadedHost& host) {
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
