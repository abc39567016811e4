// Host files: CPU sets (cpus: rt and housekeeping, configs/partitioned.yaml) and the
// rule that the network's receive threads run below every real-time task.
#include "host_loader.h"

#include <algorithm>

namespace rack {

// A CPU set: a number, a list of numbers, or a cpulist text ("0-1,3"); every CPU
// online. Returns false (with an error at the node) otherwise.
bool CpuPartition::read_cpu_set(const YAML::Node& node, const std::string& key, std::vector<int>& out) {
  const auto add = [&](int64_t c) {
    if (c < 0 || c >= CPU_SETSIZE || !caps_.cpu_online(static_cast<int>(c))) {
      std::string online;
      for (int o : caps_.online_cpus) {
        if (!online.empty()) online += ',';
        online += std::to_string(o);
      }
      std::string message = "'cpus: ";
      message += key;
      message += "': CPU ";
      message += std::to_string(c);
      message += " is not online (online: ";
      message += online;
      message += ')';
      error(node.Mark(), message);
      return false;
    }
    out.push_back(static_cast<int>(c));
    return true;
  };
  const auto bad = [&] {
    error(node.Mark(), "'cpus: " + key + "' must be a CPU number, a list of them or a CPU list such as \"0-1,3\"");
    return false;
  };
  if (node.IsSequence()) {
    for (const auto& n : node) {
      int64_t c = 0;
      if (!n.IsScalar()) return bad();
      try {
        c = n.as<int64_t>();
      } catch (const YAML::Exception&) {
        return bad();
      }
      if (!add(c)) return false;
    }
  } else if (node.IsScalar()) {
    const std::string text = node.Scalar();
    std::size_t i = 0;
    const auto number = [&](int64_t& v) {
      if (i >= text.size() || text[i] < '0' || text[i] > '9') return false;
      v = 0;
      while (i < text.size() && text[i] >= '0' && text[i] <= '9' && v < 100000) v = v * 10 + (text[i++] - '0');
      return true;
    };
    while (i < text.size()) {
      int64_t a = 0, b = 0;
      if (!number(a)) return bad();
      b = a;
      if (i < text.size() && text[i] == '-') {
        ++i;
        if (!number(b) || b < a) return bad();
      }
      for (int64_t c = a; c <= b; ++c) {
        if (!add(c)) return false;
      }
      if (i < text.size() && text[i++] != ',') return bad();
      if (i == text.size() && text.back() == ',') return bad();
    }
  } else {
    return bad();
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  if (out.empty()) return bad();
  return true;
}

// The `cpus:` block: rt and housekeeping CPU sets (configs/partitioned.yaml).
void CpuPartition::read_cpus(const YAML::Node& node, HostSettings& hs) {
  if (!node.IsMap()) {
    error(node.Mark(), "'cpus' must be a map (rt, housekeeping)");
    return;
  }
  check_keys(node, {"rt", "housekeeping"}, "cpus");
  const YAML::Node rt_node = node["rt"], hk_node = node["housekeeping"];
  if (!rt_node && !hk_node) {
    error(node.Mark(), "'cpus' needs 'rt' or 'housekeeping' (or both)");
    return;
  }
  std::vector<int> rt_set, hk_set;
  if (rt_node && !read_cpu_set(rt_node, "rt", rt_set)) return;
  if (hk_node && !read_cpu_set(hk_node, "housekeeping", hk_set)) return;
  const auto rest = [&](const std::vector<int>& other) {
    std::vector<int> r;
    for (int c : caps_.online_cpus) {
      if (std::find(other.begin(), other.end(), c) == other.end()) r.push_back(c);
    }
    return r;
  };
  if (!rt_node) rt_set = rest(hk_set);
  if (!hk_node) hk_set = rest(rt_set);
  if (rt_set.empty() || hk_set.empty()) {
    const std::string what = rt_set.empty() ? "the RT tasks" : "housekeeping";
    error(node.Mark(), "'cpus': no CPU is left for " + what + " (name both 'rt' and 'housekeeping')");
    return;
  }
  hs.rt_cpus = rt_set;
  hs.housekeeping_cpus = hk_set;
}

// The network's receive threads must never preempt a real-time task of a component
// (DESIGN: RT tasks never wait for the network): tims.receive_priority stays below
// every SCHED_FIFO task's priority.
void CpuPartition::check_receive_priority(const YAML::Node& root, const LoadedHost& host) {
  const int rx = host.settings.receive_priority;
  if (rx == 0) return;
  for (const auto& c : host.components) {
    const ComponentSettings& s = c->settings();
    const bool has_data_task = c->data_task_mode() != DataTaskMode::kNone;
    for (const auto& [task, prio] : {std::pair{"command_task", s.command_task.priority},
                                     std::pair{"data_task", has_data_task ? s.data_task.priority : 0}}) {
      if (prio > 0 && prio <= rx) {
        error(root["tims"]["receive_priority"].Mark(), "'receive_priority' = " + std::to_string(rx) +
                                                           " must be below every real-time task's priority; " + s.name +
                                                           "'s " + task + " runs at " + std::to_string(prio));
        return;
      }
    }
  }
}

}  // namespace rack
