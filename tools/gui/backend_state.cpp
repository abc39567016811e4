// rack-gui's backend: discovery, component states, statistics and latency, class
// descriptions (backend_impl.h).
#include "backend_impl.h"

namespace rack::gui {

void Backend::Impl::refresh_hosts() {
  forget_silent_hosts();
  for (auto& [key, h] : hosts) h.alive = false;
  for (const auto& h : transport.hosts()) {
    const std::string key = h.host + "#" + std::to_string(h.system) + "/" + std::to_string(h.host_id);
    Host& host = hosts[key];
    host.name = h.host;
    host.system = h.system;
    host.host_id = h.host_id;
    host.pid = h.pid;
    host.alive = true;
    host.silent_since_ns = 0;
    host.network = h.network;
    for (std::size_t i = 0; i < h.components.size(); ++i) {
      const auto& c = h.components[i];
      const uint32_t raw = c.address.component().raw();
      auto [it, fresh] = components.try_emplace(raw);
      Component& comp = it->second;
      if (fresh || comp.host_key != key) {
        // A component is shown on the host that announced it last (it moved, or
        // a router re-announced it before its executor did).
        if (!fresh && h.role != tims::NodeRole::kExecutor && hosts[comp.host_key].alive) continue;
        comp.host_key = key;
      }
      comp.info = c;
      comp.info.address = c.address.component();
      comp.system = c.address.system();
      comp.order = i;
    }
  }
}

void Backend::Impl::forget_silent_hosts() {
  const int64_t now = rt::monotonic_ns();
  std::vector<std::string> gone;
  for (auto& [key, h] : hosts) {
    if (h.alive) continue;
    if (h.silent_since_ns == 0) h.silent_since_ns = now;
    if (config.host_forget_ms >= 0 && now - h.silent_since_ns > int64_t{config.host_forget_ms} * rt::kNsPerMs) {
      gone.push_back(key);
    }
  }
  for (const auto& key : gone) {
    std::size_t removed = 0;
    for (auto it = components.begin(); it != components.end();) {
      if (it->second.host_key == key) {
        it = components.erase(it);
        ++removed;
      } else {
        ++it;
      }
    }
    const std::string text = "host " + hosts[key].name + " (" + key + ") silent for " +
                             std::to_string(config.host_forget_ms / 1000) + " s: removed from the list with its " +
                             std::to_string(removed) + " components";
    std::fprintf(stderr, "rack-gui: %s\n", text.c_str());
    broadcast(dump(json{{"type", "notice"}, {"level", "info"}, {"text", text}}));
    hosts.erase(key);
  }
}

std::string Backend::Impl::shown_state(const Component& c, int64_t now) const {
  if (c.state == "not_available") return c.state;
  if (c.last_reply_ns == 0 || now - c.last_reply_ns > kStaleNs) return "no_reply";
  return c.state;
}

void Backend::Impl::poll_status() {
  for (auto& [raw, c] : components) {
    if (c.status_pending) continue;
    c.status_pending = true;
    const Address a(raw);
    request(a, msg::kGetStatus, [this, raw](const Reply* r) {
      auto it = components.find(raw);
      if (it == components.end()) return;
      Component& comp = it->second;
      comp.status_pending = false;
      if (r == nullptr) return;  // stays until kStaleNs passes: then "no_reply"
      switch (r->header.type) {
        case msg::kEnabled: comp.state = "enabled"; break;
        case msg::kDisabled: comp.state = "disabled"; break;
        case msg::kError: comp.state = "error"; break;
        case msg::kNotAvailable: comp.state = "not_available"; break;
        default: return;
      }
      comp.last_reply_ns = rt::monotonic_ns();
      // Its class by name (the list, addresses, the panels' components) as soon as
      // it answers: rack-gui links no class.
      if (comp.state != "not_available") (void)described(Address(raw));
    });
  }
}

void Backend::Impl::poll_stats() {
  for (auto& [raw, c] : components) {
    if (c.stats_pending || shown_state(c, rt::monotonic_ns()) == "no_reply") continue;
    c.stats_pending = true;
    request(Address(raw), msg::kGetStats, [this, raw](const Reply* r) {
      auto it = components.find(raw);
      if (it == components.end()) return;
      it->second.stats_pending = false;
      wire::StatsReply st;
      if (r == nullptr || r->header.type != msg::kStats || !wire::read_payload(r->body, r->native(), st)) return;
      it->second.stats = {{"period_ns", st.period_ns},
                          {"data_task", st.data_task},
                          {"cycles", st.data.cycles},
                          {"overruns", st.data.overruns},
                          {"samples", st.data.samples},
                          {"latency_ns",
                           {{"min", st.data.latency_min_ns},
                            {"p50", st.data.latency_p50_ns},
                            {"p99", st.data.latency_p99_ns},
                            {"p999", st.data.latency_p999_ns},
                            {"max", st.data.latency_max_ns},
                            {"mean", st.data.latency_mean_ns}}},
                          {"published", st.published},
                          {"listeners", st.listeners},
                          {"commands", st.commands},
                          {"errors", st.errors},
                          {"malformed", st.malformed},
                          {"command_drops", st.command_drops}};
    });
  }
}

void Backend::Impl::poll_latency() {
  for (auto& [raw, c] : components) {
    if (c.latency_pending || c.latency_refused || shown_state(c, rt::monotonic_ns()) == "no_reply") continue;
    if (c.stats.is_object() && c.stats.value("data_task", 0) == 0) continue;
    c.latency_pending = true;
    request(Address(raw), msg::kGetLatency, [this, raw](const Reply* r) {
      auto it = components.find(raw);
      if (it == components.end()) return;
      it->second.latency_pending = false;
      if (r == nullptr) return;
      // A rackd from before GET_LATENCY answers ERROR (and counts it as malformed):
      // asking it again every second would only raise its count.
      if (r->header.type == msg::kError) it->second.latency_refused = true;
      if (r->header.type != msg::kLatency) return;
      wire::LatencyHistogram h;
      std::string why;
      if (!wire::read_payload(r->body, r->native(), h)) {
        why = "reply of " + std::to_string(r->body.size()) + " bytes, expected " + std::to_string(sizeof h);
      } else {
        auto j = latency_json(h);
        if (auto* ok = std::get_if<json>(&j)) {
          it->second.latency = std::move(*ok);
          return;
        }
        why = std::get<std::string>(j);
      }
      it->second.latency = nullptr;  // never a stale histogram beside new stats
      {
        const std::lock_guard lock(counters_mutex);
        ++counters.bad_replies;
      }
      if (!it->second.latency_bad_logged) {
        it->second.latency_bad_logged = true;
        std::fprintf(stderr, "rack-gui: %s: GET_LATENCY: malformed reply: %s (counted; logged once)\n",
                     address_text(Address(raw)).c_str(), why.c_str());
      }
    });
  }
}

const ClassInfo* Backend::Impl::described(Address a) {
  const uint32_t key = a.raw() & 0xFFFF0000u;
  ClassInfo& ci = class_infos[key];
  if (ci.desc) return &ci;
  if (ci.pending) return nullptr;
  // A refusal (a component asked while it was still starting) is asked again after a
  // while, never every round and never given up for good.
  constexpr int64_t kClassRetryNs = 2 * rt::kNsPerSec;
  if (ci.failed) {
    if (rt::monotonic_ns() - ci.failed_ns < kClassRetryNs) return nullptr;
    ci.failed = false;
    ci.pages = rack::ClassPageAssembler{};
  }
  ci.pending = true;
  rack::ClassPageRequest q;
  q.offset = ci.pages.next_offset();
  q.sections = rack::kClassSectionValueNames;  // enum and address names (the "names" object)
  request(a.component(), msg::kGetClass, q, [this, key, a](const Reply* r) {
    ClassInfo& info = class_infos[key];
    info.pending = false;
    if (r == nullptr) {  // asked again in a later round; a browser waiting is told now
      answer_class_waiters(key, a, nullptr, "no reply to GET_CLASS in time (host gone or busy?)");
      return;
    }
    std::string error;
    if (r->header.type != msg::kClass) {
      error = r->header.type == msg::kError ? "refused: " + error_reason(r->body)
                                            : "reply " + std::to_string(r->header.type);
    } else if (info.pages.add(r->body, r->native(), error) && !info.pages.complete()) {
      (void)described(a);  // the next page
      return;
    }
    rack::ClassDescription d;
    if (error.empty() && !rack::decode_class_description(info.pages.bytes(), d, error)) error = "description: " + error;
    if (error.empty() && d.class_id != a.class_id()) error = "describes another class id";
    if (!error.empty()) {
      info.failed = true;
      info.failed_ns = rt::monotonic_ns();
      answer_class_waiters(key, a, nullptr, "its class description could not be read: " + error);
      {
        const std::lock_guard lock(counters_mutex);
        ++counters.bad_replies;
      }
      if (!info.failure_said) {  // said once; it is asked again every kClassRetryNs
        info.failure_said = true;
        std::fprintf(stderr, "rack-gui: %s: GET_CLASS: %s (its data is not shown until it answers)\n",
                     address_text(a).c_str(), error.c_str());
      }
      return;
    }
    info.desc = std::move(d);
    if (info.desc->data) info.data_fields = info.desc->data->field_table();
    answer_class_waiters(key, a, &*info.desc, "");
    std::string message = class_message(a.system(), *info.desc);
    {
      const std::lock_guard lock(greet_mutex);
      class_messages[key] = message;
    }
    gdos.set_class_name(key, info.desc->class_name);  // the log's sources by that name
    broadcast(std::move(message));
  });
  return nullptr;
}

void Backend::Impl::answer_class_waiters(uint32_t key, Address a, const rack::ClassDescription* d,
                                         const std::string& why) {
  const auto it = class_waiters.find(key);
  if (it == class_waiters.end()) return;
  auto waiting = std::move(it->second);
  class_waiters.erase(it);
  for (const auto& [client, r] : waiting) {
    if (d != nullptr) {
      send_to(client, class_message(r.component.system(), *d, address_text(r.component)));
      result(client, r, true, address_text(r.component) + ": class " + d->class_name + " described");
    } else {
      result(client, r, false, address_text(a.component()) + ": " + why);
    }
  }
}

std::string Backend::Impl::class_of(Address a) const {
  if (tims::class_name(a.class_id()) == nullptr) {
    const auto it = class_infos.find(a.raw() & 0xFFFF0000u);
    if (it != class_infos.end() && it->second.desc) return it->second.desc->class_name;
  }
  return class_text(a);
}

bool Backend::Impl::resolve_component(uint64_t client, Request& r) {
  if (r.component_class.empty()) return true;
  for (const auto& [raw, c] : components) {
    const Address a(raw);
    if (a.system() != r.component.system() || a.instance() != r.component.instance()) continue;
    if (class_of(a) == r.component_class || c.info.impl == r.component_class) {
      r.component = a;
      r.component_class.clear();
      return true;
    }
  }
  result(client, r, false,
         r.component_class + "(" + std::to_string(r.component.system()) + "/" + std::to_string(r.component.instance()) +
             "): no component of that class is known at that system and instance (yet: its class is described "
             "when it first answers)");
  return false;
}

std::string Backend::Impl::components_message() const {
  const int64_t now = rt::monotonic_ns();
  std::map<uint8_t, std::map<std::string, std::vector<const Component*>>> by_robot;
  for (const auto& [raw, c] : components) by_robot[c.system][c.host_key].push_back(&c);
  json robots_j = json::array();
  for (auto& [system, by_host] : by_robot) {
    json hosts_j = json::array();
    for (auto& [key, list] : by_host) {
      std::sort(list.begin(), list.end(), [](const Component* a, const Component* b) { return a->order < b->order; });
      const auto h = hosts.find(key);
      json comps = json::array();
      for (const Component* c : list) {
        comps.push_back({{"address", address_text(c->info.address)},
                         {"name", c->info.name},
                         {"class", class_of(c->info.address)},
                         {"impl", c->info.impl},
                         {"state", shown_state(*c, now)},
                         {"stats", c->stats},
                         {"latency", c->latency}});
      }
      json hj = {{"key", key}, {"components", comps}};
      if (h != hosts.end()) {
        hj["host"] = h->second.name;
        hj["host_id"] = h->second.host_id;
        hj["pid"] = h->second.pid;
        hj["alive"] = h->second.alive;
        if (!h->second.alive && h->second.silent_since_ns != 0) {
          hj["silent_ms"] = (now - h->second.silent_since_ns) / rt::kNsPerMs;
          hj["forget_ms"] = config.host_forget_ms;
        }
        hj["network"] = h->second.network;
      }
      hosts_j.push_back(hj);
    }
    const auto r = robots.find(system);
    robots_j.push_back({{"system", system}, {"hosts", hosts_j}, {"joystick", r != robots.end() && r->second.claimed}});
  }
  return dump(json{{"type", "components"}, {"robots", robots_j}});
}

std::optional<Address> Backend::Impl::find(uint8_t system, std::string_view cls) const {
  std::optional<Address> best;
  bool best_alive = false;
  const int64_t now = rt::monotonic_ns();
  for (const auto& [raw, c] : components) {
    const Address a(raw);
    if (a.system() != system || class_of(a) != cls) continue;
    const bool alive = shown_state(c, now) == "enabled";
    if (!best || (alive && !best_alive)) {
      best = a;
      best_alive = alive;
    }
  }
  return best;
}

}  // namespace rack::gui
