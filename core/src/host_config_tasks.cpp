// Host files: a task's scheduling (priority, CPU, stack, its modeswitch mode) and the
// host's modeswitch: block (configs/modeswitch_demo.yaml documents it).
#include "host_loader.h"

namespace rack {

// min_priority 0 (data tasks only) means normal scheduling (SCHED_OTHER): for heavy,
// allocating components such as MCL that must not compete with the control tasks.
// Command tasks stay SCHED_FIFO: they answer ON/OFF and must stay responsive.
void TaskReader::read_task(const YAML::Node& node, TaskSettings& task, const std::string& where,
                           const std::set<std::string>& extra_keys, int64_t min_priority) {
  std::set<std::string> keys{"priority", "cpu", "stack_kib", "modeswitch"};
  keys.insert(extra_keys.begin(), extra_keys.end());
  check_keys(node, keys, where);
  int64_t v = 0;
  if (get_int_range(node, "priority", min_priority, 99, v,
                    min_priority == 0 ? "an integer priority 0..99 (0: normal scheduling)"
                                      : "an integer priority 1..99")) {
    task.priority = static_cast<int>(v);
  }
  if (node["cpu"]) {
    if (get(node, "cpu", v, "a CPU number")) {
      if (v < 0 || v >= CPU_SETSIZE || !caps_.cpu_online(static_cast<int>(v))) {
        std::string online;
        for (int c : caps_.online_cpus) {
          // Not `(empty ? "" : ",") + to_string(c)`: GCC 12 warns (-Wrestrict) on that
          // form once this function is compiled on its own.
          if (!online.empty()) online += ',';
          online += std::to_string(c);
        }
        error(node["cpu"].Mark(), "CPU " + std::to_string(v) + " is not online (online: " + online + ")");
      } else {
        task.cpu = static_cast<int>(v);
      }
    }
  }
  if (get_int_range(node, "stack_kib", 16, 65536, v, "a stack size in KiB (16..65536)")) {
    task.stack_bytes = static_cast<std::size_t>(v) * 1024;
  }
  if (node["modeswitch"]) task.modeswitch = get_mode(node, "modeswitch");
}

std::optional<rt::modeswitch::Mode> TaskReader::get_mode(const YAML::Node& map, const char* key) {
  std::string text;
  if (!get(map, key, text, "off, warn or abort")) return std::nullopt;
  const auto mode = rt::modeswitch::parse_mode(text);
  if (!mode) error(map[key].Mark(), std::string("'") + key + "' must be off, warn or abort, got '" + text + "'");
  return mode;
}

// The host file's `modeswitch:` block (configs/modeswitch_demo.yaml documents it).
void TaskReader::read_modeswitch(const YAML::Node& node, rt::modeswitch::Config& c) {
  if (!node.IsMap()) {
    error(node.Mark(), "'modeswitch' must be a map (mode, abort, crash_dir, ...)");
    return;
  }
  check_keys(node,
             {"mode", "abort", "crash_dir", "crash_handlers", "syscalls", "faults", "allocations", "locks", "rusage",
              "lock_wait_us", "watchdog_periods", "rttime_ms", "allow_syscalls", "stderr", "stderr_per_second",
              "repeat_ms"},
             "modeswitch");
  if (node["mode"]) {
    if (const auto m = get_mode(node, "mode")) c.default_mode = *m;
  }
  std::string text;
  if (get(node, "abort", text, "component or process")) {
    if (text == "component") c.abort_action = rt::modeswitch::AbortAction::kComponent;
    else if (text == "process") c.abort_action = rt::modeswitch::AbortAction::kProcess;
    else
      error(node["abort"].Mark(),
            "'abort' must be component (to ERROR) or process (abort, core dump), got '" + text + "'");
  }
  if (get(node, "crash_dir", text, "a directory")) {
    if (text.empty()) error(node["crash_dir"].Mark(), "'crash_dir' must not be empty");
    else c.crash_dir = resolve_path(base_dir_, text);
  }
  get(node, "crash_handlers", c.crash_handlers, "true or false");
  get(node, "syscalls", c.syscalls, "true or false");
  get(node, "faults", c.faults, "true or false");
  get(node, "allocations", c.allocations, "true or false");
  get(node, "locks", c.locks, "true or false");
  get(node, "rusage", c.rusage, "true or false");
  get(node, "stderr", c.to_stderr, "true or false");
  int64_t v = 0;
  if (get_int_range(node, "lock_wait_us", 1, 60'000'000, v, "a wait in microseconds")) c.lock_wait_ns = v * 1000;
  if (get_int_range(node, "watchdog_periods", 0, 1'000'000, v, "a number of periods (0: off)")) {
    c.watchdog_periods = static_cast<uint32_t>(v);
  }
  // Milliseconds as floats, as every *_ms (docs/parameters.md).
  if (int64_t ns = 0; get_ms_range(node, "rttime_ms", 0, 3'600'000, ns, "milliseconds, 0: off")) {
    c.rttime_us = ns / 1000;
  }
  if (int64_t ns = 0; get_ms_range(node, "repeat_ms", 0, 86'400'000, ns, "milliseconds, 0: every report in full")) {
    c.repeat_every_ns = ns;
  }
  if (get_int_range(node, "stderr_per_second", 0, 1'000'000, v, "a report count")) {
    c.stderr_per_second = static_cast<uint32_t>(v);
  }
  if (const YAML::Node list = node["allow_syscalls"]) {
    if (!list.IsSequence()) {
      error(list.Mark(), "'allow_syscalls' must be a list of system call names");
    } else {
      for (const auto& n : list) {
        if (!n.IsScalar() || rt::modeswitch::syscall_number(n.Scalar()) < 0) {
          error(n.Mark(), "'" + (n.IsScalar() ? n.Scalar() : std::string("?")) +
                              "' is not a system call of this kernel (names as in man 2 syscalls)");
          continue;
        }
        c.allow_syscalls.push_back(n.Scalar());
      }
    }
  }
}

}  // namespace rack
