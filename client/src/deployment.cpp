#include "rack/client/deployment.h"

#include <dirent.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <set>

#include "rack/core/payload_json.h"
#include "rack/core/wire.h"
#include "rack/core/wire_tasks.h"
#include "rack/tims/address.h"
#include "yaml_tree.h"

namespace rack::deploy {
namespace {

using yaml_tree::Node;

std::optional<int64_t> to_int(const std::string& s) {
  int64_t v = 0;
  const char* end = s.data() + s.size();
  const auto r = std::from_chars(s.data(), end, v);
  if (r.ec != std::errc() || r.ptr != end || s.empty()) return std::nullopt;
  return v;
}

std::optional<double> to_double(const std::string& s) {
  if (s.empty() || s.size() > 64) return std::nullopt;
  double v = 0.0;
  const char* end = s.data() + s.size();
  const auto r = std::from_chars(s.data(), end, v);
  if (r.ec != std::errc() || r.ptr != end || !std::isfinite(v)) return std::nullopt;
  return v;
}

// The TiMS class of an implementation: the longest class name TiMS knows that begins
// it ("ChassisSim" -> Chassis), or nothing.
std::optional<uint8_t> class_of_impl(const std::string& impl) {
  std::optional<uint8_t> best;
  std::size_t best_len = 0;
  for (int id = 1; id < 256; ++id) {
    const char* name = tims::class_name(static_cast<uint8_t>(id));
    if (name == nullptr) continue;
    const std::size_t n = std::strlen(name);
    if (n > best_len && impl.compare(0, n, name) == 0) {
      best = static_cast<uint8_t>(id);
      best_len = n;
    }
  }
  return best;
}

struct Reader {
  Host& out;
  void error(const Node* n, std::string why) {
    out.errors.push_back({out.file, n != nullptr ? n->line : 0, n != nullptr ? n->column : 0, std::move(why)});
  }
  const Node* scalar(const Node* map, const char* key, std::string& value) {
    const Node* n = map->find(key);
    if (n == nullptr) return nullptr;
    if (n->kind != Node::Kind::kScalar) {
      error(n, std::string("'") + key + "' must be a scalar");
      return nullptr;
    }
    value = n->value;
    return n;
  }
  // An integer in lo..hi; false (and an error) when given but not one.
  bool integer(const Node* map, const char* key, int64_t lo, int64_t hi, int& value) {
    std::string text;
    const Node* n = scalar(map, key, text);
    if (n == nullptr) return false;
    const auto v = to_int(text);
    if (!v || *v < lo || *v > hi) {
      error(n, std::string("'") + key + "' must be an integer " + std::to_string(lo) + ".." + std::to_string(hi));
      return false;
    }
    value = static_cast<int>(*v);
    return true;
  }
  // A CPU set as rackd takes it: a number, a list ([1, 2]) or a CPU list text ("1-3,5").
  void cpu_list(const Node* n, const char* what, std::vector<int>& cpus) {
    if (n == nullptr) return;
    const auto bad = [&](const Node* at) {
      error(at, std::string("'") + what + "': a CPU number 0..4095, a list of them or a CPU list like \"1-3,5\"");
    };
    if (n->kind == Node::Kind::kList) {
      for (const Node* item : n->items) {
        const auto v = item->kind == Node::Kind::kScalar ? to_int(item->value) : std::nullopt;
        if (!v || *v < 0 || *v > 4095) bad(item);
        else cpus.push_back(static_cast<int>(*v));
      }
      return;
    }
    if (n->kind != Node::Kind::kScalar) return bad(n);
    std::size_t at = 0;
    const std::string& text = n->value;
    while (at <= text.size()) {
      const std::size_t comma = std::min(text.find(',', at), text.size());
      const std::string part = text.substr(at, comma - at);
      const std::size_t dash = part.find('-');
      const auto lo = to_int(part.substr(0, dash));
      const auto hi = dash == std::string::npos ? lo : to_int(part.substr(dash + 1));
      if (!lo || !hi || *lo < 0 || *hi > 4095 || *lo > *hi) return bad(n);
      for (int64_t c = *lo; c <= *hi; ++c) cpus.push_back(static_cast<int>(c));
      at = comma + 1;
    }
  }
  void task(const Node* n, const char* what, Task& t, int min_priority) {
    if (n == nullptr) return;
    if (n->kind != Node::Kind::kMap) {
      error(n, std::string("'") + what + "' must be a map (priority, cpu, ...)");
      return;
    }
    if (const Node* p = n->find("priority")) {
      t.line = p->line;
      t.column = p->column;
    } else {
      t.line = n->line;
      t.column = n->column;
    }
    integer(n, "priority", min_priority, 99, t.priority);
    integer(n, "cpu", 0, 4095, t.cpu);
  }

  void read(const Node* root) {
    if (root == nullptr || root->kind != Node::Kind::kMap) {
      error(root, "a host file is a map (host, system, components, ...)");
      return;
    }
    scalar(root, "host", out.host);
    integer(root, "system", 0, 255, out.system);
    integer(root, "host_id", 0, 255, out.host_id);
    scalar(root, "lcm_url", out.lcm_url);
    if (const Node* cpus = root->find("cpus"); cpus != nullptr) {
      if (cpus->kind != Node::Kind::kMap) error(cpus, "'cpus' must be a map (rt, housekeeping)");
      else {
        cpu_list(cpus->find("rt"), "rt", out.rt_cpus);
        cpu_list(cpus->find("housekeeping"), "housekeeping", out.housekeeping_cpus);
      }
    }
    if (const Node* tims = root->find("tims"); tims != nullptr && tims->kind == Node::Kind::kMap) {
      scalar(tims, "role", out.role);
      if (const Node* nets = tims->find("networks"); nets != nullptr) {
        if (nets->kind != Node::Kind::kList) error(nets, "'networks' must be a list of {name, url, scope}");
        else {
          for (const Node* item : nets->items) {
            if (item->kind != Node::Kind::kMap) {
              error(item, "a network is a map (name, url, scope)");
              continue;
            }
            Network net;
            scalar(item, "name", net.name);
            scalar(item, "url", net.url);
            scalar(item, "scope", net.scope);
            out.networks.push_back(std::move(net));
          }
        }
      }
    }
    const Node* comps = root->find("components");
    if (comps == nullptr) return;
    if (comps->kind != Node::Kind::kList) {
      error(comps, "'components' must be a list");
      return;
    }
    for (const Node* item : comps->items) {
      if (out.components.size() >= kMaxComponentsPerHost) {
        error(item, "more than " + std::to_string(kMaxComponentsPerHost) + " components");
        break;
      }
      if (item->kind != Node::Kind::kMap) {
        error(item, "a component is a map (name, class, instance, tasks, params)");
        continue;
      }
      Component c;
      c.line = item->line;
      c.column = item->column;
      if (scalar(item, "name", c.name) == nullptr) error(item, "component without 'name'");
      if (scalar(item, "class", c.impl) == nullptr) error(item, "component '" + c.name + "' has no 'class'");
      integer(item, "instance", 0, 255, c.instance);
      task(item->find("command_task"), "command_task", c.command_task, 1);
      if (const Node* dt = item->find("data_task")) {
        c.has_data_task = true;
        task(dt, "data_task", c.data_task, 0);
        if (dt->kind == Node::Kind::kMap) {
          std::string ms;
          if (const Node* pn = scalar(dt, "period_ms", ms)) {
            const auto v = to_double(ms);
            if (!v || *v <= 0 || *v > 86'400'000) error(pn, "'period_ms' must be a positive number of milliseconds");
            else c.period_ns = static_cast<int64_t>(std::llround(*v * 1e6));
          }
        }
      }
      if (const Node* params = item->find("params"); params != nullptr) {
        if (params->kind != Node::Kind::kMap) error(params, "'params' must be a map");
        else {
          for (std::size_t i = 0; i + 1 < params->items.size(); i += 2) {
            const Node* k = params->items[i];
            const Node* v = params->items[i + 1];
            if (k->kind != Node::Kind::kScalar) continue;
            c.params.push_back(
                {k->value, v->kind == Node::Kind::kScalar ? v->value : std::string(), v->line, v->column});
          }
        }
      }
      if (const auto cls = class_of_impl(c.impl)) {
        c.class_name = tims::class_name(*cls);
        c.address = tims::Address::make(static_cast<uint8_t>(out.system), *cls, static_cast<uint8_t>(c.instance)).raw();
        c.address_text = tims::Address(*c.address).str();
      } else {
        c.address_text = c.impl + "(" + std::to_string(out.system) + "/" + std::to_string(c.instance) + ")?";
      }
      out.components.push_back(std::move(c));
    }
  }
};

std::string ms_text(int64_t ns) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", static_cast<double>(ns) / 1e6);
  return std::string(buf) + " ms";
}

std::string dot_escape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) continue;
    out += c;
  }
  return out;
}

std::string quoted(const std::string& s) { return "\"" + json_escape(s) + "\""; }

// A priority in JSON: null when not known.
std::string priority_json(int priority) { return priority < 0 ? std::string("null") : std::to_string(priority); }
// "[0,2]".
std::string int_list_json(const std::vector<int>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i == 0 ? "" : ",") + std::to_string(v[i]);
  return s + "]";
}
// A task's cpu in JSON: -1 not pinned, null when not known (Host::tasks_known, a
// priority not known); a running task on a set of CPUs adds "cpus".
std::string cpu_json(const Host& h, const Task& t) {
  if (!h.tasks_known || t.priority < 0) return "null";
  return std::to_string(t.cpu) + (t.cpus.empty() ? "" : ",\"cpus\":" + int_list_json(t.cpus));
}
// One task as it runs (GET_TASKS) in JSON.
std::string running_json(const RunningTask& r) {
  return "{\"measured\":" + std::string(r.measured ? "true" : "false") +
         ",\"policy\":" + (r.measured ? "\"" + r.policy + "\"" : std::string("null")) +
         ",\"priority\":" + priority_json(r.priority) + ",\"cpus\":" + int_list_json(r.cpus) +
         ",\"last_cpu\":" + (r.last_cpu >= 0 ? std::to_string(r.last_cpu) : std::string("null")) +
         ",\"configured_priority\":" + priority_json(r.configured_priority) +
         ",\"configured_cpu\":" + std::to_string(r.configured_cpu) + ",\"period_ns\":" + std::to_string(r.period_ns) +
         ",\"measured_period_ns\":" + std::to_string(r.measured_period_ns) + "}";
}

// What a component found by discovery alone cannot say when it does not answer
// GET_TASKS (an older rackd): its tasks' priorities and CPUs are in its host file.
constexpr const char* kTasksNotKnown = "priority and cpu not known without the host file";

// "30", or "?" when not known.
std::string priority_text(int priority) { return priority < 0 ? std::string("?") : std::to_string(priority); }

// "0-3,5" for sorted CPU numbers.
std::string cpu_list_text(const std::vector<int>& cpus) {
  std::string s;
  for (std::size_t i = 0; i < cpus.size();) {
    std::size_t j = i;
    while (j + 1 < cpus.size() && cpus[j + 1] == cpus[j] + 1) ++j;
    s += (s.empty() ? "" : ",") + std::to_string(cpus[i]);
    if (j > i) s += (j == i + 1 ? "," : "-") + std::to_string(cpus[j]);
    i = j + 1;
  }
  return s;
}

std::string cpu_label(const Host& h, const Task& t) {
  if (!h.tasks_known || t.priority < 0) return kTasksNotKnown;
  if (t.cpu >= 0) return "cpu " + std::to_string(t.cpu);
  if (!t.cpus.empty()) return "cpus " + cpu_list_text(t.cpus);
  if (t.priority > 0 && !h.rt_cpus.empty()) {
    std::string s = "rt cpus ";
    for (std::size_t i = 0; i < h.rt_cpus.size(); ++i) s += (i == 0 ? "" : ",") + std::to_string(h.rt_cpus[i]);
    return s;
  }
  return "any cpu";
}

std::string task_text(const Host& h, const Component& c) {
  if (!h.tasks_known || c.command_task.priority < 0) {
    std::string s = "tasks: priority and cpu not known";
    if (c.has_data_task) s += c.period_ns > 0 ? "\ndata task every " + ms_text(c.period_ns) : "\ndata task triggered";
    return s;
  }
  std::string s = "cmd p" + priority_text(c.command_task.priority) + " " + cpu_label(h, c.command_task);
  if (c.has_data_task) {
    s += "\ndata p" + priority_text(c.data_task.priority) + " " + cpu_label(h, c.data_task);
    s += c.period_ns > 0 ? ", every " + ms_text(c.period_ns) : ", triggered";
  }
  return s;
}

const LiveTask* live_task(const Live* live, std::size_t h, std::size_t c) {
  if (live == nullptr || h >= live->tasks.size() || c >= live->tasks[h].size()) return nullptr;
  return &live->tasks[h][c];
}

std::string live_text(const LiveTask& t) {
  std::string s = t.state;
  if (t.utilisation >= 0) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f%%", t.utilisation * 100.0);
    s += std::string(", util ") + buf;
  }
  if (t.worst_latency_ns >= 0) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0f us", static_cast<double>(t.worst_latency_ns) / 1e3);
    s += std::string(", worst wake-up ") + buf;
  }
  if (t.tasks_known && t.has_data_task && t.data.measured_period_ns > 0) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.1f ms", static_cast<double>(t.data.measured_period_ns) / 1e6);
    s += std::string(", runs every ") + buf;
  }
  return s;
}

// A task's CPUs as it runs: the one CPU, else the set ("" when it may run on any).
std::string running_cpus_text(const RunningTask& t, int online_cpus) {
  if (t.cpus.size() == 1) return "cpu " + std::to_string(t.cpus.front());
  if (t.cpus.empty() || (online_cpus > 0 && t.cpus.size() >= static_cast<std::size_t>(online_cpus))) return "";
  return "cpus " + cpu_list_text(t.cpus);
}

// The kernel's name of a policy number (sched.h).
const char* policy_name(int policy) {
  switch (policy) {
    case 0: return "SCHED_OTHER";
    case 1: return "SCHED_FIFO";
    case 2: return "SCHED_RR";
    case 3: return "SCHED_BATCH";
    case 5: return "SCHED_IDLE";
    case 6: return "SCHED_DEADLINE";
    default: return "?";
  }
}

// The network of `h` with `scope`, else its first, else its lcm_url's name.
std::string network_of(const Host& h, const char* scope) {
  for (const auto& n : h.networks) {
    if (n.scope == scope) return n.name;
  }
  if (!h.networks.empty()) return h.networks.front().name;
  return h.lcm_url.empty() ? "default" : h.lcm_url;
}

std::vector<std::string> crossed(const std::vector<Host>& hosts, std::size_t a, std::size_t b) {
  if (a == b) return {};
  const Host& ha = hosts[a];
  const Host& hb = hosts[b];
  // A network both join (by name and URL): the flow stays on it.
  for (const auto& na : ha.networks) {
    for (const auto& nb : hb.networks) {
      if (na.name == nb.name && na.url == nb.url) return {na.name};
    }
  }
  if (ha.networks.empty() && hb.networks.empty() && ha.lcm_url == hb.lcm_url) return {network_of(ha, "robot")};
  // Otherwise through the system routers: the producer's robot network, the fleet
  // link, the consumer's robot network.
  std::vector<std::string> path{network_of(ha, "robot")};
  std::string fleet;
  for (const auto& h : hosts) {
    for (const auto& n : h.networks) {
      if (n.scope == "fleet" && fleet.empty()) fleet = n.name;
    }
  }
  if (!fleet.empty() && fleet != path.back()) path.push_back(fleet);
  const std::string last = network_of(hb, "robot");
  if (last != path.back()) path.push_back(last);
  return path;
}

// An address as a host file gives it: Name(system/instance), the class by name.
struct Reference {
  std::string cls;
  int system = 0;
  int instance = 0;
};
std::optional<Reference> parse_reference(const std::string& text) {
  const std::size_t open = text.find('(');
  const std::size_t slash = text.find('/', open);
  const std::size_t close = text.find(')', slash == std::string::npos ? open : slash);
  if (open == 0 || open == std::string::npos || slash == std::string::npos || close == std::string::npos ||
      close + 1 != text.size()) {
    return std::nullopt;
  }
  const auto sys = to_int(text.substr(open + 1, slash - open - 1));
  const auto inst = to_int(text.substr(slash + 1, close - slash - 1));
  if (!sys || !inst || *sys < 0 || *sys > 255 || *inst < 0 || *inst > 255) return std::nullopt;
  Reference r{text.substr(0, open), static_cast<int>(*sys), static_cast<int>(*inst)};
  // A class given as a number (Class0x40(1/0), 64(1/0)) is named as TiMS names it.
  if (const auto a = tims::parse_address(text); a && tims::class_name(a->class_id()) != nullptr) {
    r.cls = tims::class_name(a->class_id());
  }
  return r;
}

// The key two components share when rackd would give them one address: the class
// (TiMS' name, else the implementation), system and instance.
std::string address_key(const Host& h, const Component& c) {
  return (c.class_name.empty() ? c.impl : c.class_name) + "(" + std::to_string(h.system) + "/" +
         std::to_string(c.instance) + ")";
}

// The component a reference names: same system and instance, and a class whose
// address name is the reference's, or whose implementation begins with it
// (ChassisSim for Chassis(0/0) when TiMS does not know the class).
std::optional<std::pair<std::size_t, std::size_t>> find_placed(
    const std::vector<Host>& hosts, const std::map<std::string, std::pair<std::size_t, std::size_t>>& placed,
    const Reference& r) {
  for (const auto& [key, at] : placed) {
    const Host& h = hosts[at.first];
    const Component& c = h.components[at.second];
    if (h.system != r.system || c.instance != r.instance) continue;
    if (c.class_name == r.cls || (c.class_name.empty() && c.impl.compare(0, r.cls.size(), r.cls) == 0)) return at;
  }
  return std::nullopt;
}

}  // namespace

std::string Host::label() const {
  if (!host.empty()) return host;
  const auto slash = file.find_last_of('/');
  return slash == std::string::npos ? file : file.substr(slash + 1);
}

Host read_host_text(const std::string& text, const std::string& file) {
  Host out;
  out.file = file;
  yaml_tree::Document doc;
  ConfigError syntax;
  if (!yaml_tree::parse_document(text, file, doc, syntax)) {
    out.errors.push_back(std::move(syntax));
    return out;
  }
  Reader{out}.read(doc.root);
  return out;
}

Host read_host(const std::string& path) {
  std::string why;
  const auto text = read_host_bytes(path, why);
  if (!text) {
    Host out;
    out.file = path;
    out.errors.push_back({path, 0, 0, why});
    return out;
  }
  return read_host_text(*text, path);
}

std::vector<std::string> host_file_paths(const std::vector<std::string>& args, std::vector<std::string>& errors) {
  std::vector<std::string> out;
  for (const auto& a : args) {
    struct stat st {};
    if (::stat(a.c_str(), &st) != 0) {
      errors.push_back(a + ": " + std::strerror(errno));
      continue;
    }
    if (!S_ISDIR(st.st_mode)) {
      out.push_back(a);
      continue;
    }
    DIR* dir = ::opendir(a.c_str());
    if (dir == nullptr) {
      errors.push_back(a + ": " + std::strerror(errno));
      continue;
    }
    std::vector<std::string> names;
    while (const dirent* e = ::readdir(dir)) {
      const std::string n = e->d_name;
      const auto ends = [&](const char* suffix) {
        const std::size_t l = std::strlen(suffix);
        return n.size() > l && n.compare(n.size() - l, l, suffix) == 0;
      };
      if (n[0] != '.' && (ends(".yaml") || ends(".yml"))) names.push_back(n);
    }
    ::closedir(dir);
    std::sort(names.begin(), names.end());
    if (names.empty()) errors.push_back(a + ": no *.yaml host files in this directory");
    const std::string prefix = a.back() == '/' ? a : a + "/";
    for (const auto& n : names) out.push_back(prefix + n);
  }
  return out;
}

// The allocation: RT tasks (priority > 0) per CPU group of each host, and the
// configuration's priority inversions among them (d.cpus, made anew).
static void allocate(Deployment& d) {
  d.cpus.clear();
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    const Host& host = d.hosts[h];
    std::map<std::string, CpuGroup> groups;
    for (std::size_t c = 0; c < host.components.size(); ++c) {
      const Component& comp = host.components[c];
      // A task whose priority is not known: under one label. A task that runs under
      // normal scheduling although its host file asked for a priority is listed too.
      const auto place = [&](const Task& t, bool data) {
        if (t.priority == 0 && t.configured_priority <= 0) return;
        CpuGroup& g = groups[cpu_label(host, t)];
        g.host = h;
        g.cpus = cpu_label(host, t);
        g.tasks.push_back({h, c, data, t.priority, data ? comp.period_ns : 0});
      };
      place(comp.command_task, false);
      if (comp.has_data_task) place(comp.data_task, true);
    }
    for (auto& [label, g] : groups) {
      if (!host.tasks_known || label == kTasksNotKnown) {  // nothing to compare: no flags
        d.cpus.push_back(std::move(g));
        continue;
      }
      // Several CPUs (or any): the tasks share one only when the others are busy.
      const bool one_cpu = label.rfind("cpu ", 0) == 0 || (label.rfind("rt cpus ", 0) == 0 && host.rt_cpus.size() == 1);
      const std::string where = one_cpu ? " on " + label : " on " + label + " (not pinned: when they share a CPU)";
      std::stable_sort(g.tasks.begin(), g.tasks.end(),
                       [](const PlacedTask& a, const PlacedTask& b) { return a.priority > b.priority; });
      // Two data tasks with one priority on one CPU: FIFO order between them, not
      // the configuration, decides who waits.
      for (std::size_t i = 0; i < g.tasks.size(); ++i) {
        for (std::size_t j = i + 1; j < g.tasks.size(); ++j) {
          const PlacedTask& a = g.tasks[i];
          const PlacedTask& b = g.tasks[j];
          if (!a.data || !b.data || a.priority != b.priority) continue;
          g.flags.push_back("same priority " + std::to_string(a.priority) + where + ": data tasks of '" +
                            host.components[a.component].name + "' and '" + host.components[b.component].name + "'");
        }
      }
      // A task that does not run at the priority its host file asked for.
      for (const PlacedTask& t : g.tasks) {
        const Component& comp = host.components[t.component];
        const Task& task = t.data ? comp.data_task : comp.command_task;
        if (task.configured_priority < 0 || task.configured_priority == task.priority) continue;
        g.flags.push_back("'" + comp.name + "' " + (t.data ? "data" : "command") + " task runs at priority " +
                          std::to_string(task.priority) + (task.priority == 0 ? " (normal scheduling)" : "") +
                          ", its host file asks for " + std::to_string(task.configured_priority));
      }
      // A consumer above its producer on one CPU.
      for (const Flow& f : d.flows) {
        if (f.consumer_host != h || f.producer_host != h) continue;
        const Component& cons = host.components[f.consumer];
        const Component& prod = host.components[f.producer];
        if (!cons.has_data_task || !prod.has_data_task || prod.data_task.priority <= 0) continue;
        if (cpu_label(host, cons.data_task) != label || cpu_label(host, prod.data_task) != label) continue;
        if (cons.data_task.priority > prod.data_task.priority) {
          const std::string through = f.live ? "a running subscription"
                                             : "'" + f.param + "' (" + host.file + ":" + std::to_string(f.line) + ":" +
                                                   std::to_string(f.column) + ")";
          g.flags.push_back("consumer above its producer" + where + ": '" + cons.name + "' (data p" +
                            std::to_string(cons.data_task.priority) + ") reads '" + prod.name + "' (data p" +
                            std::to_string(prod.data_task.priority) + ") through " + through);
        }
      }
      d.cpus.push_back(std::move(g));
    }
  }
}

Deployment build(std::vector<Host> hosts, const std::vector<ClassInfo>* classes) {
  Deployment d;
  d.hosts = std::move(hosts);
  const auto info_of = [&](const Component& c) -> const ClassInfo* {
    if (classes == nullptr) return nullptr;
    for (const auto& ci : *classes) {
      if (ci.impl == c.impl) return &ci;
    }
    return nullptr;
  };
  // The classes' own names for their addresses.
  for (auto& host : d.hosts) {
    for (auto& c : host.components) {
      const ClassInfo* ci = info_of(c);
      if (ci == nullptr || ci->class_name.empty() || ci->class_name == c.class_name) continue;
      c.class_name = ci->class_name;
      const std::string where = "(" + std::to_string(host.system) + "/" + std::to_string(c.instance) + ")";
      std::optional<uint8_t> id = tims::class_id(ci->class_name);
      if (!id && ci->class_id > 0 && ci->class_id < 256) id = static_cast<uint8_t>(ci->class_id);  // a plug-in's
      if (id) {
        c.address = tims::Address::make(static_cast<uint8_t>(host.system), *id, static_cast<uint8_t>(c.instance)).raw();
        c.address_text = ci->class_name + where;
      } else {
        c.address.reset();
        c.address_text = ci->class_name + where + "?";
      }
    }
  }
  // Every placed address, for flows across hosts and duplicate checks.
  std::map<std::string, std::pair<std::size_t, std::size_t>> placed;  // by address_key
  std::map<std::string, std::size_t> host_names;
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    const Host& host = d.hosts[h];
    if (!host.host.empty()) {
      if (const auto [it, fresh] = host_names.emplace(host.host, h); !fresh) {
        d.problems.push_back(host.file + ": host '" + host.host + "' is also " + d.hosts[it->second].file);
      }
    }
    for (std::size_t c = 0; c < host.components.size(); ++c) {
      const Component& comp = host.components[c];
      if (comp.impl.empty()) continue;
      if (const auto [it, fresh] = placed.emplace(address_key(host, comp), std::pair{h, c}); !fresh) {
        const auto& [oh, oc] = it->second;
        d.problems.push_back(host.file + ":" + std::to_string(comp.line) + ":" + std::to_string(comp.column) +
                             ": component '" + comp.name + "' has the address " + comp.address_text + " of '" +
                             d.hosts[oh].components[oc].name + "' in " + d.hosts[oh].file);
      }
    }
  }
  // Flows: parameters naming a component of the same file, or an address.
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    const Host& host = d.hosts[h];
    for (std::size_t c = 0; c < host.components.size(); ++c) {
      const ClassInfo* ci = info_of(host.components[c]);
      for (const Param& p : host.components[c].params) {
        if (p.value.empty()) continue;
        if (ci != nullptr && ci->described && std::find(ci->refs.begin(), ci->refs.end(), p.key) == ci->refs.end()) {
          continue;  // the class says this parameter names no component
        }
        Flow f;
        f.consumer_host = h;
        f.consumer = c;
        f.target = p.value;
        f.param = p.key;
        f.line = p.line;
        f.column = p.column;
        bool is_ref = false;
        for (std::size_t o = 0; o < host.components.size(); ++o) {
          if (o != c && host.components[o].name == p.value) {
            f.producer_host = h;
            f.producer = o;
            is_ref = true;
          }
        }
        if (!is_ref && p.value.find('(') != std::string::npos) {
          if (const auto ref = parse_reference(p.value)) {
            is_ref = true;
            if (const auto at = find_placed(d.hosts, placed, *ref)) {
              f.producer_host = at->first;
              f.producer = at->second;
            }
          }
        }
        if (!is_ref) continue;
        if (f.producer != kNone) {
          f.period_ns = d.hosts[f.producer_host].components[f.producer].period_ns;
          f.networks = crossed(d.hosts, f.producer_host, h);
        }
        d.flows.push_back(std::move(f));
      }
    }
  }
  allocate(d);
  return d;
}

const char* add_listeners(const Deployment& d, std::size_t h, std::size_t c, std::span<const std::byte> body,
                          bool native, Live& live) {
  if (h >= d.hosts.size() || c >= d.hosts[h].components.size()) return "no such component in the deployment";
  wire::ListenersReply r;
  if (const char* bad = wire::decode_listeners(body, native, r)) return bad;
  if (live.listeners_known.size() < d.hosts.size()) live.listeners_known.resize(d.hosts.size());
  auto& known = live.listeners_known[h];
  if (known.size() < d.hosts[h].components.size()) known.resize(d.hosts[h].components.size(), false);
  known[c] = true;
  for (std::size_t i = 0; i < r.count; ++i) {
    LiveFlow f;
    f.producer_host = h;
    f.producer = c;
    f.listener = r.mailbox[i];
    f.period_ns = r.listener_period_ns[i];
    live.flows.push_back(f);
  }
  return nullptr;
}

const char* add_tasks(const Deployment& d, std::size_t h, std::size_t c, std::span<const std::byte> body, bool native,
                      Live& live) {
  if (h >= d.hosts.size() || c >= d.hosts[h].components.size()) return "no such component in the deployment";
  wire::TasksReply r;
  if (const char* bad = wire::decode_tasks(body, native, r)) return bad;
  if (live.tasks.size() < d.hosts.size()) live.tasks.resize(d.hosts.size());
  if (live.tasks[h].size() < d.hosts[h].components.size()) live.tasks[h].resize(d.hosts[h].components.size());
  LiveTask& t = live.tasks[h][c];
  t.tasks_known = true;
  t.has_data_task = r.data_task != 0;
  t.online_cpus = static_cast<int>(r.online_cpus);
  for (std::size_t i = 0; i < r.task_count && i < wire::kTaskRecords; ++i) {
    RunningTask& run = i == 0 ? t.command : t.data;
    run = RunningTask{};
    run.configured_priority = r.configured_priority[i];
    run.configured_cpu = r.configured_cpu[i];
    run.period_ns = r.period_ns[i];
    run.measured_period_ns = r.measured_period_ns[i];
    if (r.measured[i] != wire::kTaskMeasured) continue;
    run.measured = true;
    run.policy = policy_name(r.policy[i]);
    run.priority = r.priority[i];
    run.last_cpu = r.last_cpu[i];
    for (std::size_t cpu = 0; cpu < wire::kTaskCpuWords * 64; ++cpu) {
      if ((r.affinity[i * wire::kTaskCpuWords + cpu / 64] >> (cpu % 64)) & 1u)
        run.cpus.push_back(static_cast<int>(cpu));
    }
  }
  t.networks.clear();
  for (std::size_t j = 0; j < r.network_count; ++j) {
    t.networks.push_back({r.name_of_network(j), r.url_of_network(j), r.network_scope[j] == 1 ? "fleet" : "robot"});
  }
  return nullptr;
}

namespace {

// A task as it runs: its priority and CPUs from the kernel's reading, else (not read
// yet) what its host file asked for.
Task running_task(const RunningTask& r, int online_cpus) {
  Task t;
  t.priority = r.measured ? r.priority : r.configured_priority;
  t.cpu = r.measured ? -1 : r.configured_cpu;
  if (r.measured && r.cpus.size() == 1) {
    t.cpu = r.cpus.front();
  } else if (r.measured && !(online_cpus > 0 && r.cpus.size() >= static_cast<std::size_t>(online_cpus))) {
    t.cpus = r.cpus;
  }
  if (r.measured && r.configured_priority != r.priority) t.configured_priority = r.configured_priority;
  return t;
}

}  // namespace

void adopt_running(Deployment& d, Live& live) {
  bool changed = false;
  for (std::size_t h = 0; h < d.hosts.size() && h < live.tasks.size(); ++h) {
    Host& host = d.hosts[h];
    if (host.tasks_known) continue;  // its host file says how it is configured
    bool any = false;                // a component that does not answer keeps priority -1: not known
    for (std::size_t c = 0; c < host.components.size(); ++c) {
      const LiveTask* t = c < live.tasks[h].size() ? &live.tasks[h][c] : nullptr;
      if (t == nullptr || !t->tasks_known) continue;
      any = true;
      Component& comp = host.components[c];
      comp.command_task = running_task(t->command, t->online_cpus);
      comp.has_data_task = t->has_data_task;
      if (t->has_data_task) {
        comp.data_task = running_task(t->data, t->online_cpus);
        comp.period_ns = t->data.period_ns;
      }
      if (host.networks.empty()) host.networks = t->networks;
      changed = true;
    }
    host.tasks_known = any;
  }
  // The networks crossed need every host's networks: after the loop above.
  for (LiveFlow& lf : live.flows) {
    if (lf.flow != kNone || lf.consumer == kNone || lf.consumer_host >= d.hosts.size() ||
        lf.producer_host >= d.hosts.size()) {
      continue;
    }
    Flow f;
    f.consumer_host = lf.consumer_host;
    f.consumer = lf.consumer;
    f.producer_host = lf.producer_host;
    f.producer = lf.producer;
    f.target = d.hosts[lf.producer_host].components[lf.producer].address_text;
    f.period_ns = lf.period_ns;
    f.networks = crossed(d.hosts, lf.producer_host, lf.consumer_host);
    f.live = true;
    lf.flow = d.flows.size();
    d.flows.push_back(std::move(f));
    if (live.flow_state.size() < d.flows.size()) live.flow_state.resize(d.flows.size(), -1);
    live.flow_state[lf.flow] = 1;
    changed = true;
  }
  if (changed) allocate(d);
}

void match_live_flows(const Deployment& d, Live& live) {
  // The component at each command address (the listener's mailbox: same system,
  // class and instance).
  std::map<uint32_t, std::pair<std::size_t, std::size_t>> at;
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    for (std::size_t c = 0; c < d.hosts[h].components.size(); ++c) {
      if (const auto& a = d.hosts[h].components[c].address)
        at.emplace(tims::Address(*a).component().raw(), std::pair{h, c});
    }
  }
  live.flow_state.assign(d.flows.size(), -1);
  for (std::size_t i = 0; i < d.flows.size(); ++i) {
    const Flow& f = d.flows[i];
    if (f.producer == kNone) continue;
    if (f.producer_host < live.listeners_known.size() && f.producer < live.listeners_known[f.producer_host].size() &&
        live.listeners_known[f.producer_host][f.producer]) {
      live.flow_state[i] = 0;  // asked: runs only when a listener below is this flow
    }
  }
  for (LiveFlow& lf : live.flows) {
    lf.consumer_host = kNone;
    lf.consumer = kNone;
    lf.flow = kNone;
    if (const auto it = at.find(tims::Address(lf.listener).component().raw()); it != at.end()) {
      lf.consumer_host = it->second.first;
      lf.consumer = it->second.second;
    }
    if (lf.consumer == kNone) continue;
    for (std::size_t i = 0; i < d.flows.size(); ++i) {
      const Flow& f = d.flows[i];
      if (f.producer_host == lf.producer_host && f.producer == lf.producer && f.consumer_host == lf.consumer_host &&
          f.consumer == lf.consumer) {
        lf.flow = i;
        live.flow_state[i] = 1;
        break;
      }
    }
  }
}

std::string listener_text(const Deployment& d, const LiveFlow& f) {
  const std::string address = tims::Address(f.listener).str();
  if (f.consumer == kNone || f.consumer_host >= d.hosts.size() ||
      f.consumer >= d.hosts[f.consumer_host].components.size()) {
    return address;
  }
  return d.hosts[f.consumer_host].components[f.consumer].name + " (" + address + ")";
}

std::string to_dot(const Deployment& d, const Live* live) {
  std::string
      s = "digraph deployment {\n  rankdir=LR;\n  compound=true;\n  node [shape=box, fontname=\"sans\", fontsize=10];\n"
          "  edge [fontname=\"sans\", fontsize=9];\n";
  std::map<int, std::vector<std::size_t>> by_system;
  for (std::size_t h = 0; h < d.hosts.size(); ++h) by_system[d.hosts[h].system].push_back(h);
  for (const auto& [system, hosts] : by_system) {
    s += "  subgraph cluster_system_" + std::to_string(system) + " {\n    label=\"system " + std::to_string(system) +
         "\";\n    style=rounded;\n";
    for (const std::size_t h : hosts) {
      const Host& host = d.hosts[h];
      const bool stale = live != nullptr && h < live->hosts.size() && !live->hosts[h].answered;
      std::string label = host.label() + " (" + host.role + ", host_id " + std::to_string(host.host_id) + ")";
      for (const auto& n : host.networks) label += "\n" + n.name + (n.scope.empty() ? "" : " [" + n.scope + "]");
      if (stale) label += "\nSTALE: did not answer discovery";
      s += "    subgraph cluster_host_" + std::to_string(h) + " {\n      label=\"" + dot_escape(label) + "\";\n";
      if (!host.errors.empty()) s += "      color=red; fontcolor=red;\n";
      else if (stale) s += "      color=grey; fontcolor=grey; style=dashed;\n";
      // An invisible anchor keeps hosts without components in the picture.
      s += "      h" + std::to_string(h) + " [shape=point, style=invis];\n";
      for (std::size_t c = 0; c < host.components.size(); ++c) {
        const Component& comp = host.components[c];
        std::string l = comp.name + "\n" + comp.address_text + " " + comp.impl + "\n" + task_text(host, comp);
        std::string attrs;
        if (const LiveTask* t = live_task(live, h, c)) {
          l += "\n" + live_text(*t);
          if (t->state == "ERROR") attrs = ", color=red, fontcolor=red";
          else if (!t->answered) attrs = ", color=grey, fontcolor=grey, style=dashed";
        }
        s += "      c" + std::to_string(h) + "_" + std::to_string(c) + " [label=\"" + dot_escape(l) + "\"" + attrs +
             "];\n";
      }
      for (std::size_t e = 0; e < host.errors.size() && e < 8; ++e) {
        s += "      e" + std::to_string(h) + "_" + std::to_string(e) +
             " [shape=note, color=red, fontcolor=red, label=\"" + dot_escape(host.errors[e].str()) + "\"];\n";
      }
      s += "    }\n";
    }
    s += "  }\n";
  }
  std::map<std::string, std::size_t> unplaced;  // target -> node number, in order of appearance
  for (const Flow& f : d.flows) {
    std::string from;
    if (f.producer == kNone) {
      const auto [it, fresh] = unplaced.emplace(f.target, unplaced.size());
      from = "u_" + std::to_string(it->second);
      if (fresh) {
        s += "  " + from + " [label=\"" + dot_escape(f.target) + "\\nnot in these host files\", style=dashed];\n";
      }
    } else {
      from = "c" + std::to_string(f.producer_host) + "_" + std::to_string(f.producer);
    }
    std::string label = f.live ? "subscribed" : f.param;
    if (f.period_ns > 0) label += ", " + ms_text(f.period_ns);
    std::string attrs;
    if (!f.networks.empty()) {
      label += "\nvia ";
      for (std::size_t i = 0; i < f.networks.size(); ++i) label += (i == 0 ? "" : " > ") + f.networks[i];
      attrs = f.networks.size() > 1 ? ", color=blue, penwidth=2" : ", color=blue";
    }
    if (f.producer == kNone) attrs += ", style=dashed";
    if (const std::size_t i = static_cast<std::size_t>(&f - d.flows.data());
        live != nullptr && i < live->flow_state.size()) {
      if (live->flow_state[i] == 1) {
        label += "\nrunning";
      } else if (live->flow_state[i] == 0) {
        label += "\nnot running";
        attrs += ", color=grey, fontcolor=grey, style=dotted";
      }
    }
    s += "  " + from + " -> c" + std::to_string(f.consumer_host) + "_" + std::to_string(f.consumer) + " [label=\"" +
         dot_escape(label) + "\"" + attrs + "];\n";
  }
  if (live != nullptr) {
    std::map<uint32_t, std::size_t> outside;  // listener mailbox -> node number
    for (const LiveFlow& lf : live->flows) {
      if (lf.flow != kNone) continue;  // drawn above
      std::string to;
      if (lf.consumer != kNone) {
        to = "c" + std::to_string(lf.consumer_host) + "_" + std::to_string(lf.consumer);
      } else {
        const auto [it, fresh] = outside.emplace(lf.listener, outside.size());
        to = "l_" + std::to_string(it->second);
        if (fresh) {
          s += "  " + to + " [label=\"" + dot_escape(listener_text(d, lf)) +
               "\\nnot in these host files (a tool?)\", style=dashed, color=darkgreen, fontcolor=darkgreen];\n";
        }
      }
      std::string label = "live only";
      if (lf.period_ns > 0) label += ", " + ms_text(lf.period_ns);
      s += "  c" + std::to_string(lf.producer_host) + "_" + std::to_string(lf.producer) + " -> " + to + " [label=\"" +
           dot_escape(label) + "\", color=darkgreen, fontcolor=darkgreen];\n";
    }
  }
  s += "}\n";
  return s;
}

std::string allocation_text(const Deployment& d, const Live* live) {
  std::string s;
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    const Host& host = d.hosts[h];
    s += host.label() + " (" + host.file + ", system " + std::to_string(host.system) + ")";
    if (live != nullptr && h < live->hosts.size() && !live->hosts[h].answered) s += "  STALE: did not answer discovery";
    s += "\n";
    for (const auto& e : host.errors) s += "  error: " + e.str() + "\n";
    bool any = false;
    for (const CpuGroup& g : d.cpus) {
      if (g.host != h) continue;
      any = true;
      s += "  " + g.cpus;
      if (g.cpus == kTasksNotKnown) {
        s += " (no GET_TASKS answer, an older rackd: rackctl alloc --live FILE|DIR ... shows its host file's)";
      }
      s += "\n";
      char line[320];
      std::snprintf(line, sizeof line, "    %-4s %-20s %-5s %-10s", "PRIO", "COMPONENT", "TASK", "PERIOD");
      s += line;
      s += live != nullptr ? " RUNS EVERY UTIL    WORST WAKE-UP  STATE\n" : "\n";
      std::vector<std::string> running_flags;  // the host file's values against what runs
      for (const PlacedTask& t : g.tasks) {
        const Component& c = host.components[t.component];
        const std::string period = !t.data ? "-" : t.period_ns > 0 ? ms_text(t.period_ns) : "triggered";
        std::snprintf(line, sizeof line, "    %-4s %-20s %-5s %-10s", priority_text(t.priority).c_str(), c.name.c_str(),
                      t.data ? "data" : "cmd", period.c_str());
        s += line;
        const LiveTask* lt = live_task(live, h, t.component);
        if (lt != nullptr && t.data) {
          char every[24] = "-";
          char util[16] = "-";
          char worst[24] = "-";
          if (lt->tasks_known && lt->data.measured_period_ns > 0) {
            std::snprintf(every, sizeof every, "%.1f ms", static_cast<double>(lt->data.measured_period_ns) / 1e6);
          }
          if (lt->utilisation >= 0) std::snprintf(util, sizeof util, "%.1f%%", lt->utilisation * 100.0);
          if (lt->worst_latency_ns >= 0) {
            std::snprintf(worst, sizeof worst, "%.0f us", static_cast<double>(lt->worst_latency_ns) / 1e3);
          }
          std::snprintf(line, sizeof line, " %-10s %-7s %-14s %s", every, util, worst, lt->state.c_str());
          s += line;
        } else if (lt != nullptr) {
          s += " -          -       -              " + lt->state;
        }
        s += "\n";
        // A host file's task that runs otherwise (RT refused, moved by chrt/taskset).
        if (lt != nullptr && lt->tasks_known) {  // (adopt_running's hosts: the same values)
          const RunningTask& run = t.data ? lt->data : lt->command;
          const Task& want = t.data ? c.data_task : c.command_task;
          if (run.measured && run.priority != want.priority) {
            running_flags.push_back("'" + c.name + "' " + (t.data ? "data" : "command") + " task runs at priority " +
                                    std::to_string(run.priority) + " (" + run.policy + "), its host file asks for " +
                                    std::to_string(want.priority));
          }
          const std::string cpus = running_cpus_text(run, lt->online_cpus);
          if (run.measured && want.cpu >= 0 && cpus != "cpu " + std::to_string(want.cpu)) {
            running_flags.push_back("'" + c.name + "' " + (t.data ? "data" : "command") + " task runs on " +
                                    (cpus.empty() ? std::string("any cpu") : cpus) + ", its host file pins it to cpu " +
                                    std::to_string(want.cpu));
          }
        }
      }
      for (const auto& f : g.flags) s += "    ! " + f + "\n";
      for (const auto& f : running_flags) s += "    ! " + f + "\n";
    }
    if (!any) s += "  no RT tasks\n";
  }
  for (const auto& p : d.problems) s += "! " + p + "\n";
  return s;
}

std::string to_json(const Deployment& d, const Live* live) {
  std::string s = "{\"hosts\":[";
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    const Host& host = d.hosts[h];
    s += (h == 0 ? "{" : ",{") + std::string("\"file\":") + quoted(host.file) + ",\"host\":" + quoted(host.label()) +
         ",\"system\":" + std::to_string(host.system) + ",\"host_id\":" + std::to_string(host.host_id) +
         ",\"role\":" + quoted(host.role) + ",\"networks\":[";
    for (std::size_t n = 0; n < host.networks.size(); ++n) {
      s += (n == 0 ? "{" : ",{") + std::string("\"name\":") + quoted(host.networks[n].name) +
           ",\"scope\":" + quoted(host.networks[n].scope) + ",\"url\":" + quoted(host.networks[n].url) + "}";
    }
    s += "],\"errors\":[";
    for (std::size_t e = 0; e < host.errors.size(); ++e) {
      const auto& err = host.errors[e];
      s += (e == 0 ? "{" : ",{") + std::string("\"line\":") + std::to_string(err.line) +
           ",\"column\":" + std::to_string(err.column) + ",\"message\":" + quoted(err.message) + "}";
    }
    s += "]";
    if (live != nullptr && h < live->hosts.size()) {
      s += ",\"answered\":" + std::string(live->hosts[h].answered ? "true" : "false");
    }
    s += ",\"components\":[";
    for (std::size_t c = 0; c < host.components.size(); ++c) {
      const Component& comp = host.components[c];
      s += (c == 0 ? "{" : ",{") + std::string("\"name\":") + quoted(comp.name) + ",\"impl\":" + quoted(comp.impl) +
           ",\"address\":" + quoted(comp.address_text) + ",\"line\":" + std::to_string(comp.line) +
           ",\"command_task\":{\"priority\":" + priority_json(comp.command_task.priority) +
           ",\"cpu\":" + cpu_json(host, comp.command_task) + "}";
      if (comp.has_data_task) {
        s += ",\"data_task\":{\"priority\":" + priority_json(comp.data_task.priority) +
             ",\"cpu\":" + cpu_json(host, comp.data_task) + ",\"period_ns\":" + std::to_string(comp.period_ns) + "}";
      }
      if (const LiveTask* t = live_task(live, h, c)) {
        s += ",\"live\":{\"state\":" + quoted(t->state) +
             ",\"utilisation\":" + (t->utilisation >= 0 ? std::to_string(t->utilisation) : std::string("null")) +
             ",\"worst_latency_ns\":" +
             (t->worst_latency_ns >= 0 ? std::to_string(t->worst_latency_ns) : std::string("null"));
        if (t->tasks_known) {
          s += ",\"running\":{\"command_task\":" + running_json(t->command);
          if (t->has_data_task) s += ",\"data_task\":" + running_json(t->data);
          s += ",\"online_cpus\":" + std::to_string(t->online_cpus) + "}";
        }
        s += "}";
      }
      s += "}";
    }
    s += "]}";
  }
  s += "],\"flows\":[";
  for (std::size_t i = 0; i < d.flows.size(); ++i) {
    const Flow& f = d.flows[i];
    s += (i == 0 ? "{" : ",{") + std::string("\"consumer\":") +
         quoted(d.hosts[f.consumer_host].components[f.consumer].name) +
         ",\"consumer_host\":" + quoted(d.hosts[f.consumer_host].label()) + ",\"param\":" + quoted(f.param) +
         ",\"target\":" + quoted(f.target) + ",\"producer\":" +
         (f.producer == kNone ? std::string("null") : quoted(d.hosts[f.producer_host].components[f.producer].name)) +
         ",\"producer_host\":" +
         (f.producer == kNone ? std::string("null") : quoted(d.hosts[f.producer_host].label())) +
         ",\"period_ns\":" + std::to_string(f.period_ns) + ",\"networks\":[";
    for (std::size_t n = 0; n < f.networks.size(); ++n) s += (n == 0 ? "" : ",") + quoted(f.networks[n]);
    s += "]";
    if (live != nullptr) {
      const int state = i < live->flow_state.size() ? live->flow_state[i] : -1;
      s += ",\"running\":" + std::string(state == 1 ? "true" : state == 0 ? "false" : "null");
    }
    s += ",\"live\":" + std::string(f.live ? "true" : "false") + "}";
  }
  if (live != nullptr) {
    s += "],\"live_flows\":[";
    for (std::size_t i = 0; i < live->flows.size(); ++i) {
      const LiveFlow& lf = live->flows[i];
      const bool placed = lf.consumer != kNone && lf.consumer_host < d.hosts.size();
      s += (i == 0 ? "{" : ",{") + std::string("\"producer\":") +
           quoted(d.hosts[lf.producer_host].components[lf.producer].name) +
           ",\"producer_host\":" + quoted(d.hosts[lf.producer_host].label()) +
           ",\"listener\":" + quoted(tims::Address(lf.listener).str()) + ",\"consumer\":" +
           (placed ? quoted(d.hosts[lf.consumer_host].components[lf.consumer].name) : std::string("null")) +
           ",\"consumer_host\":" + (placed ? quoted(d.hosts[lf.consumer_host].label()) : std::string("null")) +
           ",\"period_ns\":" + std::to_string(lf.period_ns) + ",\"in_files\":" +
           (lf.flow != kNone && lf.flow < d.flows.size() && !d.flows[lf.flow].live ? "true" : "false") + "}";
    }
  }
  s += "],\"cpus\":[";
  for (std::size_t i = 0; i < d.cpus.size(); ++i) {
    const CpuGroup& g = d.cpus[i];
    s += (i == 0 ? "{" : ",{") + std::string("\"host\":") + quoted(d.hosts[g.host].label()) +
         ",\"cpus\":" + quoted(g.cpus) + ",\"tasks\":[";
    for (std::size_t t = 0; t < g.tasks.size(); ++t) {
      const PlacedTask& p = g.tasks[t];
      s += (t == 0 ? "{" : ",{") + std::string("\"component\":") +
           quoted(d.hosts[g.host].components[p.component].name) + ",\"task\":" + quoted(p.data ? "data" : "command") +
           ",\"priority\":" + priority_json(p.priority) + ",\"period_ns\":" + std::to_string(p.period_ns) + "}";
    }
    s += "],\"flags\":[";
    for (std::size_t f = 0; f < g.flags.size(); ++f) s += (f == 0 ? "" : ",") + quoted(g.flags[f]);
    s += "]}";
  }
  s += "],\"problems\":[";
  for (std::size_t i = 0; i < d.problems.size(); ++i) s += (i == 0 ? "" : ",") + quoted(d.problems[i]);
  s += "]}";
  return s;
}

}  // namespace rack::deploy
