#include "rack/core/host_config.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include "rack/core/data_component.h"
#include "rack/tims/lcm_url.h"
#include "rack/tims/link_auth.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <sstream>

namespace rack {

namespace {

// Length in bytes of the UTF-8 sequence at text[i] and its code point; 0 when the
// bytes there are not well-formed UTF-8 (overlong, surrogate, above U+10FFFF, cut).
std::size_t utf8_sequence(std::string_view text, std::size_t i, uint32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(text[i + k]); };
  const unsigned char c = b(0);
  std::size_t n = 0;
  if (c < 0x80) {
    cp = c;
    return 1;
  }
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
    cp = c & 0x1Fu;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    cp = c & 0x0Fu;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    cp = c & 0x07u;
  } else return 0;
  if (i + n > text.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xC0u) != 0x80u) return 0;
    cp = (cp << 6) | (b(k) & 0x3Fu);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

// A control character (C0 but tab and newline, DEL, C1) or a line/paragraph
// separator: nothing a name or value in a host file needs, all of it something that
// garbles a log line or a terminal.
bool is_control(uint32_t cp) {
  return (cp < 0x20 && cp != '\t' && cp != '\n') || (cp >= 0x7F && cp <= 0x9F) || cp == 0x2028 || cp == 0x2029;
}

std::string byte_text(unsigned char c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02x", c);
  return buf;
}

std::string code_point_text(uint32_t cp) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "U+%04X", cp);
  return buf;
}

// The first reason a string is not clean text (NUL, a control character, invalid
// UTF-8), or "" when it is.
std::string unclean_text(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    uint32_t cp = 0;
    const std::size_t n = utf8_sequence(text, i, cp);
    if (n == 0)
      return "invalid UTF-8 (byte " + byte_text(static_cast<unsigned char>(text[i])) + " at offset " +
             std::to_string(i) + ")";
    if (cp == 0) return "a NUL byte at offset " + std::to_string(i);
    if (is_control(cp)) return "a control character (" + code_point_text(cp) + ") at offset " + std::to_string(i);
    i += n;
  }
  return {};
}

// A message as it may be printed: invalid UTF-8 and control characters (newline and
// tab too) as '?',
// at most kMaxMessage bytes.
std::string clean_message(const std::string& message) {
  constexpr std::size_t kMaxMessage = 1024;
  std::string out;
  for (std::size_t i = 0; i < message.size() && out.size() < kMaxMessage;) {
    uint32_t cp = 0;
    const std::size_t n = utf8_sequence(message, i, cp);
    if (n == 0 || cp < 0x20 || is_control(cp)) {  // a newline too: one message, one line
      out += '?';
      i += n == 0 ? 1 : n;
    } else {
      out.append(message, i, n);
      i += n;
    }
  }
  if (out.size() >= kMaxMessage) out += "...";
  return out;
}

// The event pass over a host file (before it is built into nodes): yaml-cpp keeps
// every pair of a map with a repeated key and its look-up finds the first (the
// loader's iteration the last), so a repeated key is found here, from the events,
// with both places. Also: nesting depth, and every scalar (key or value, after
// escapes) is clean text of at most kMaxHostScalarBytes.
class HostFileEvents final : public YAML::EventHandler {
 public:
  HostFileEvents(const std::string& file, std::vector<ConfigError>& errors) : file_(file), errors_(errors) {}

  int documents = 0;
  YAML::Mark second_document;

  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents == 2) second_document = mark;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { node(mark, nullptr); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { node(mark, nullptr); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t, const std::string& value) override {
    if (documents > 1) return;
    if (value.size() > kMaxHostScalarBytes) {
      error(mark, "a value of " + std::to_string(value.size()) + " bytes: at most " +
                      std::to_string(kMaxHostScalarBytes) + " bytes per key or value");
    } else if (const std::string why = unclean_text(value); !why.empty()) {
      error(mark, "this value holds " + why + ": keys and values are UTF-8 text without control characters");
    }
    node(mark, &value);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(mark, nullptr);
    push(mark, false);
  }
  void OnSequenceEnd() override { pop(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(mark, nullptr);
    push(mark, true);
  }
  void OnMapEnd() override { pop(); }

 private:
  struct Frame {
    bool map = false;
    bool want_key = true;
    std::map<std::string, YAML::Mark> keys;
  };
  void error(const YAML::Mark& m, const std::string& message) {
    errors_.push_back({file_, m.line + 1, m.column + 1, message});
  }
  void node(const YAML::Mark& mark, const std::string* scalar) {
    if (documents > 1 || stack_.empty() || !stack_.back().map) return;
    Frame& f = stack_.back();
    if (f.want_key && scalar != nullptr) {
      const auto [it, fresh] = f.keys.emplace(*scalar, mark);
      if (!fresh) {
        error(mark, "duplicate key '" + *scalar + "' (first at line " + std::to_string(it->second.line + 1) +
                        "): a key may appear once in a map");
      }
    }
    f.want_key = !f.want_key;
  }
  void push(const YAML::Mark& mark, bool map) {
    if (documents > 1) return;
    if (stack_.size() == kMaxHostNesting && !deep_reported_) {
      error(mark, "nested deeper than " + std::to_string(kMaxHostNesting) + " levels");
      deep_reported_ = true;
    }
    stack_.push_back(Frame{map, true, {}});
  }
  void pop() {
    if (!stack_.empty() && documents <= 1) stack_.pop_back();
  }

  const std::string& file_;
  std::vector<ConfigError>& errors_;
  std::vector<Frame> stack_;
  bool deep_reported_ = false;
};

}  // namespace

// Friend of Component: sets settings and resolved references.
struct HostLoader {
  std::string file;
  ComponentRegistry& registry;
  const rt::RtCapabilities& caps;
  HostLoadOptions options;
  std::vector<ConfigError> errors;
  // The host file's folder, absolute: every relative path the file holds (plug-ins,
  // key files, crash_dir, parameters with a Parameter::Spec::path) is taken from here.
  std::string base_dir;
  // Every component's address by name (filled while loading them, even when another
  // component has errors, so that the access rules resolve names regardless).
  std::map<std::string, tims::Address> component_addresses;

  void error(const YAML::Mark& mark, const std::string& message) {
    errors.push_back({file, mark.line + 1, mark.column + 1, message});
  }
  std::vector<ConfigError> warnings;
  void warn(const YAML::Mark& mark, const std::string& message) {
    warnings.push_back({file, mark.line + 1, mark.column + 1, message});
  }

  // What an error about a path adds when the file gave it relative.
  std::string relative_note(const std::string& given) const {
    if (given.empty() || given.front() == '/') return {};
    return " ('" + given + "' is relative to the host file's folder, " + base_dir + ")";
  }

  // --check: the files and folders a component's parameters name exist (what init()
  // or the first STORE_DATA would otherwise find out after the start).
  void check_parameter_paths(const YAML::Node& node, const std::string& name, const ParameterSet& params,
                             const std::map<const Parameter*, YAML::Mark>& marks) {
    for (std::size_t i = 0; i < params.size(); ++i) {
      const Parameter& prm = params.at(i);
      const PathRole role = prm.spec().path;
      if (role == PathRole::kNone || role == PathRole::kDevice) continue;
      const std::string value = prm.get_string();
      if (value.empty()) continue;
      const auto at = marks.find(&prm);
      const YAML::Mark mark = at != marks.end() ? at->second : node.Mark();
      const std::string given = at != marks.end() ? node["params"][prm.name()].Scalar() : value;
      std::string target = value;
      if (role == PathRole::kOutput) {
        const auto slash = value.find_last_of('/');
        target = slash == std::string::npos ? "." : slash == 0 ? "/" : value.substr(0, slash);
      }
      const char* what = role == PathRole::kInput ? "" : role == PathRole::kOutput ? "the folder of " : "";
      struct stat st {};
      std::string problem;
      if (::stat(target.c_str(), &st) != 0) {
        const int e = errno;
        problem = std::string(what) + target + ": " + std::strerror(e);
      } else if (role != PathRole::kInput && !S_ISDIR(st.st_mode)) {
        problem = target + ": not a folder";
      }
      if (!problem.empty()) {
        error(mark, "component '" + name + "': parameter '" + prm.name() + "': " + problem + relative_note(given));
      }
    }
  }

  // Checks that a map has only known keys; reports each unknown one.
  void check_keys(const YAML::Node& map, const std::set<std::string>& known, const std::string& where) {
    for (auto it = map.begin(); it != map.end(); ++it) {
      const std::string key = it->first.Scalar();
      if (known.count(key) == 0) {
        std::string list;
        for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
        error(it->first.Mark(), "unknown key '" + key + "' in " + where + " (known: " + list + ")");
      }
    }
  }

  template <typename T>
  bool get(const YAML::Node& map, const char* key, T& out, const std::string& what) {
    const YAML::Node n = map[key];
    if (!n) return false;
    if (!n.IsScalar()) {
      error(n.Mark(), std::string("'") + key + "' must be " + what);
      return false;
    }
    try {
      out = n.as<T>();
      return true;
    } catch (const YAML::Exception&) {
      error(n.Mark(), std::string("'") + key + "' must be " + what + ", got '" + n.Scalar() + "'");
      return false;
    }
  }

  bool get_int_range(const YAML::Node& map, const char* key, int64_t lo, int64_t hi, int64_t& out,
                     const std::string& what) {
    int64_t v = 0;
    if (!get(map, key, v, what)) return false;
    if (v < lo || v > hi) {
      error(map[key].Mark(), std::string("'") + key + "' = " + std::to_string(v) + " is outside " + std::to_string(lo) +
                                 ".." + std::to_string(hi));
      return false;
    }
    out = v;
    return true;
  }

  bool get_positive_ms(const YAML::Node& map, const char* key, int64_t& out_ns) {
    double ms = 0;
    if (!get(map, key, ms, "a number of milliseconds")) return false;
    if (!(ms > 0) || !std::isfinite(ms)) {
      error(map[key].Mark(), std::string("'") + key + "' must be positive, got " + map[key].Scalar());
      return false;
    }
    if (ms > kMaxHostMilliseconds) {
      error(map[key].Mark(), std::string("'") + key + "' = " + map[key].Scalar() + " is above " +
                                 std::to_string(static_cast<int64_t>(kMaxHostMilliseconds)) + " ms (a day)");
      return false;
    }
    out_ns = static_cast<int64_t>(std::llround(ms * 1e6));
    if (out_ns <= 0) {
      error(map[key].Mark(), std::string("'") + key + "' is below one nanosecond");
      return false;
    }
    return true;
  }

  // min_priority 0 (data tasks only) means normal scheduling (SCHED_OTHER): for heavy,
  // allocating components such as MCL that must not compete with the control tasks.
  // Command tasks stay SCHED_FIFO: they answer ON/OFF and must stay responsive.
  void read_task(const YAML::Node& node, TaskSettings& task, const std::string& where,
                 const std::set<std::string>& extra_keys, int64_t min_priority = 1) {
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
        if (v < 0 || v >= CPU_SETSIZE || !caps.cpu_online(static_cast<int>(v))) {
          std::string online;
          for (int c : caps.online_cpus) online += (online.empty() ? "" : ",") + std::to_string(c);
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

  std::optional<rt::modeswitch::Mode> get_mode(const YAML::Node& map, const char* key) {
    std::string text;
    if (!get(map, key, text, "off, warn or abort")) return std::nullopt;
    const auto mode = rt::modeswitch::parse_mode(text);
    if (!mode) error(map[key].Mark(), std::string("'") + key + "' must be off, warn or abort, got '" + text + "'");
    return mode;
  }

  // The host file's `modeswitch:` block (configs/modeswitch_demo.yaml documents it).
  void read_modeswitch(const YAML::Node& node, rt::modeswitch::Config& c) {
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
      else c.crash_dir = resolve_path(base_dir, text);
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
    if (get_int_range(node, "rttime_ms", 0, 3'600'000, v, "milliseconds (0: off)")) c.rttime_us = v * 1000;
    if (get_int_range(node, "repeat_ms", 0, 86'400'000, v, "milliseconds (0: every report in full)")) {
      c.repeat_every_ns = v * 1'000'000;
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

  // A name: 1..max ASCII letters, digits, '_', '-' (and '.' where `dots`).
  static bool valid_name(const std::string& n, std::size_t max = kMaxNameLength, bool dots = false) {
    if (n.empty() || n.size() > max) return false;
    for (char c : n) {
      const bool letter = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
      if (!letter && c != '_' && c != '-' && !(dots && c == '.')) return false;
    }
    return true;
  }

  // A name as it may be shown in a message: cut to 40 characters, non-ASCII and
  // control bytes as '?' (the message itself must stay clean text).
  static std::string printable(const std::string& n) {
    std::string out;
    for (char c : n.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
    if (n.size() > 40) out += "...(" + std::to_string(n.size()) + " bytes)";
    return out;
  }

  void check_url(const YAML::Node& map, const char* key, const std::string& url) {
    if (const auto u = tims::parse_lcm_url(url); !u.ok())
      error(map[key].Mark(), std::string("'") + key + "': " + u.error);
  }

  // The raw bytes, before YAML sees them: size, NUL bytes, UTF-8, control characters
  // (tab, newline and carriage return aside). False: not parsed at all.
  bool check_text(std::string_view text) {
    if (text.size() > kMaxHostFileBytes) {
      errors.push_back({file, 0, 0,
                        "the host file has " + std::to_string(text.size()) + " bytes: at most " +
                            std::to_string(kMaxHostFileBytes) + " are read"});
      return false;
    }
    int line = 1, column = 1;
    for (std::size_t i = 0; i < text.size();) {
      uint32_t cp = 0;
      const std::size_t n = utf8_sequence(text, i, cp);
      std::string why;
      if (n == 0) why = "invalid UTF-8 (byte " + byte_text(static_cast<unsigned char>(text[i])) + ")";
      else if (cp == 0) why = "a NUL byte";
      else if (is_control(cp) && cp != '\r') why = "a control character (" + code_point_text(cp) + ")";
      if (!why.empty()) {
        errors.push_back({file, line, column, why + ": a host file is UTF-8 text without control characters"});
        return false;
      }
      if (cp == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
      i += n;
    }
    return true;
  }

  // The event pass (HostFileEvents) and the rule of one document. False: the first
  // document is not YAML.
  bool check_events(const std::string& text) {
    std::istringstream in(text);
    YAML::Parser parser(in);
    HostFileEvents events(file, errors);
    try {
      parser.HandleNextDocument(events);
    } catch (const YAML::Exception& e) {
      error(e.mark, "YAML syntax: " + e.msg);
      return false;
    }
    // Whatever follows the first document (after '---' or '...') is refused, not
    // ignored: yaml-cpp's Load would read the first and drop the rest unseen.
    try {
      if (parser.HandleNextDocument(events)) {
        error(events.second_document,
              "a second YAML document: a host file is one document (remove the '---' and "
              "what follows)");
      }
    } catch (const YAML::Exception& e) {
      error(e.mark, "after the host file's document: a host file is one document (YAML syntax: " + e.msg + ")");
    }
    return true;
  }

  LoadResult load(const std::string& text) {
    LoadResult result;
    YAML::Node root;
    if (!check_text(text) || !check_events(text)) {
      result.errors = errors;
      return result;
    }
    try {
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      error(e.mark, "YAML syntax: " + e.msg);
      result.errors = errors;
      return result;
    }
    if (!root || root.IsNull()) {
      errors.push_back({file, 0, 0, "empty host file (expected a map with 'components')"});
      result.errors = errors;
      return result;
    }
    if (!root.IsMap()) {
      error(root.Mark(), "a host file is a map (host, system, components, ...)");
      result.errors = errors;
      return result;
    }
    auto host = std::make_unique<LoadedHost>();
    HostSettings& hs = host->settings;
    hs.file = file;
    base_dir = host_file_folder(file);
    check_keys(root,
               {"host", "system", "host_id", "require_rt", "lcm", "lcm_url", "heap_prefault_mib", "cpu_dma_latency_us",
                "trace_ring_events", "cpus", "plugins", "modeswitch", "components", "gdos", "tims", "access"},
               "the host file");
    char hostname[256] = {};
    gethostname(hostname, sizeof hostname - 1);
    hs.host = hostname;
    if (get(root, "host", hs.host, "a host name") && !valid_name(hs.host, kMaxHostNameLength, true)) {
      error(root["host"].Mark(), "host name '" + printable(hs.host) + "' must be 1.." +
                                     std::to_string(kMaxHostNameLength) + " letters, digits, '.', '_' or '-'");
    }
    int64_t v = 0;
    if (get_int_range(root, "system", 0, 254, v, "a system (robot) id 0..254")) hs.system = static_cast<uint8_t>(v);
    if (get_int_range(root, "host_id", 0, 255, v, "a host id 0..255")) hs.host_id = static_cast<uint8_t>(v);
    get(root, "require_rt", hs.require_rt, "true or false");
    get(root, "lcm", hs.lcm, "true or false");
    hs.lcm_url = tims_default_url();
    if (get(root, "lcm_url", hs.lcm_url, "an LCM URL such as udpm://239.255.76.67:7667?ttl=0")) {
      check_url(root, "lcm_url", hs.lcm_url);
    }
    if (get_int_range(root, "heap_prefault_mib", 0, 16384, v, "a size in MiB")) {
      hs.heap_prefault_bytes = static_cast<std::size_t>(v) << 20;
    }
    if (get_int_range(root, "cpu_dma_latency_us", -1, 100000, v,
                      "a latency bound in us (0: shallowest idle state; -1: leave to the system)")) {
      hs.cpu_dma_latency_us = static_cast<int>(v);
    }
    if (get_int_range(root, "trace_ring_events", 16, 1 << 20, v, "a number of events (a power of two)")) {
      if ((v & (v - 1)) != 0) {
        error(root["trace_ring_events"].Mark(),
              "'trace_ring_events' = " + std::to_string(v) + " is not a power of two (e.g. 1024, 4096, 16384)");
      } else {
        hs.trace_ring_events = static_cast<std::size_t>(v);
      }
    }
    if (const YAML::Node cpus = root["cpus"]) read_cpus(cpus, hs);
    if (const YAML::Node ms = root["modeswitch"]) read_modeswitch(ms, hs.modeswitch);
    if (const YAML::Node t = root["tims"]) load_tims(t, hs, root["lcm_url"].IsDefined());
    if (const YAML::Node plugins = root["plugins"]) {
      if (!plugins.IsSequence()) {
        error(plugins.Mark(), "'plugins' must be a list of plug-in directories or shared library paths");
      } else {
        for (const auto& p : plugins) {
          if (!p.IsScalar()) {
            error(p.Mark(), "a plug-in is a path");
            continue;
          }
          if (p.Scalar().empty()) {
            error(p.Mark(), "a plug-in path must not be empty");
            continue;
          }
          if (!options.open_files) continue;
          const std::string path = resolve_path(base_dir, p.Scalar());
          // A directory is searched for plug-in classes by name (<Class>.rack-class,
          // loaded only when a component names the class); a file is loaded now.
          struct stat st {};
          if (::stat(path.c_str(), &st) != 0) {
            const int e = errno;
            error(p.Mark(), "plug-in " + path + ": " + std::strerror(e) + relative_note(p.Scalar()));
            continue;
          }
          if (S_ISDIR(st.st_mode)) {
            registry.add_plugin_dir(path);
            hs.plugins.push_back(path);
            continue;
          }
          try {
            registry.load_plugin(path);
            hs.plugins.push_back(path);
          } catch (const std::exception& e) {
            error(p.Mark(), e.what());
          }
        }
      }
    }
    if (const YAML::Node g = root["gdos"]) read_gdos(g, hs.gdos);
    const YAML::Node comps = root["components"];
    if (!comps) {
      errors.push_back({file, 0, 0, "missing 'components' (the list of components to run)"});
    } else if (!comps.IsSequence()) {
      error(comps.Mark(), "'components' must be a list");
    } else {
      load_components(comps, *host);
    }
    if (const YAML::Node a = root["access"]) read_access(a, *host);
    check_receive_priority(root, *host);
    if (!errors.empty()) {
      result.errors = errors;
      return result;
    }
    result.host = std::move(host);
    result.warnings = warnings;
    return result;
  }

  void read_gdos(const YAML::Node& g, GdosSettings& out) {
    if (!g.IsMap()) {
      error(g.Mark(), "'gdos' must be a map (level, stderr, ring, drain_ms, lcm, lcm_url, channel)");
      return;
    }
    check_keys(g, {"level", "stderr", "ring", "drain_ms", "lcm", "lcm_url", "channel"}, "gdos");
    std::string text;
    if (get(g, "level", text, std::string("a GDOS level (") + gdos::kLevelNames + ")")) {
      if (const auto l = gdos::parse_level(text)) out.level = *l;
      else
        error(g["level"].Mark(), "'level' must be one of " + std::string(gdos::kLevelNames) + ", got '" + text + "'");
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

  // The network's receive threads must never preempt a real-time task of a component
  // (DESIGN: RT tasks never wait for the network): tims.receive_priority stays below
  // every SCHED_FIFO task's priority.
  // A CPU set: a number, a list of numbers, or a cpulist text ("0-1,3"); every CPU
  // online. Returns false (with an error at the node) otherwise.
  bool read_cpu_set(const YAML::Node& node, const std::string& key, std::vector<int>& out) {
    const auto add = [&](int64_t c) {
      if (c < 0 || c >= CPU_SETSIZE || !caps.cpu_online(static_cast<int>(c))) {
        std::string online;
        for (int o : caps.online_cpus) {
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
  void read_cpus(const YAML::Node& node, HostSettings& hs) {
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
      for (int c : caps.online_cpus) {
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

  void check_receive_priority(const YAML::Node& root, const LoadedHost& host) {
    const int rx = host.settings.receive_priority;
    if (rx == 0) return;
    for (const auto& c : host.components) {
      const ComponentSettings& s = c->settings();
      const bool has_data_task = c->data_task_mode() != DataTaskMode::kNone;
      for (const auto& [task, prio] : {std::pair{"command_task", s.command_task.priority},
                                       std::pair{"data_task", has_data_task ? s.data_task.priority : 0}}) {
        if (prio > 0 && prio <= rx) {
          error(root["tims"]["receive_priority"].Mark(),
                "'receive_priority' = " + std::to_string(rx) + " must be below every real-time task's priority; " +
                    s.name + "'s " + task + " runs at " + std::to_string(prio));
          return;
        }
      }
    }
  }

  static std::string tims_default_url() { return "udpm://239.255.76.67:7667?ttl=0"; }

  // The `tims:` section: role, discovery timing, message limits, networks.
  void load_tims(const YAML::Node& t, HostSettings& hs, bool have_lcm_url) {
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
        error(n["name"].Mark(), "network name '" + printable(nc.name) + "' must be 1.." +
                                    std::to_string(kMaxNameLength) + " letters, digits, '_' or '-'");
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
  bool read_access_addresses(const YAML::Node& node, const char* key, std::vector<tims::AddressMask>& out,
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
  void read_access(const YAML::Node& a, LoadedHost& host) {
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

  void load_components(const YAML::Node& comps, LoadedHost& host) {
    struct Pending {
      YAML::Node node;
      std::unique_ptr<Component> component;
      std::vector<std::pair<Parameter*, YAML::Node>> refs;
    };
    std::vector<Pending> pending;
    std::map<std::string, std::size_t> by_name;
    std::map<uint32_t, std::size_t> by_address;
    for (const auto& node : comps) {
      if (!node.IsMap()) {
        error(node.Mark(), "a component is a map (name, class, instance, tasks, params)");
        continue;
      }
      check_keys(node,
                 {"name", "class", "instance", "autostart", "retry_ms", "rpc_timeout_ms", "rpc_retries", "command_task",
                  "data_task", "params"},
                 "a component");
      std::string name, impl;
      if (!node["name"]) {
        error(node.Mark(), "component without 'name'");
        continue;
      }
      if (!get(node, "name", name, "a name")) continue;
      if (!valid_name(name)) {
        error(node["name"].Mark(), "component name '" + printable(name) + "' must be 1.." +
                                       std::to_string(kMaxNameLength) + " letters, digits, '_' or '-'");
        continue;
      }
      if (!node["class"]) {
        error(node.Mark(), "component '" + name + "' has no 'class'");
        continue;
      }
      if (!get(node, "class", impl, "a component class name")) continue;
      // A class that is not built in is looked up as a plug-in by its name and loaded
      // (only when files may be opened: --check does, a fuzz run does not).
      std::string why;
      const ComponentClass* cls = options.open_files ? registry.resolve(impl, why) : registry.find(impl);
      if (cls == nullptr) {
        error(node["class"].Mark(),
              why.empty() ? "unknown component class '" + impl + "' (known: " + registry.names() + ")" : why);
        continue;
      }
      ComponentSettings s;
      s.name = name;
      s.impl = impl;
      s.base_dir = base_dir;
      int64_t instance = 0;
      get_int_range(node, "instance", 0, 255, instance, "an instance number 0..255");
      s.address = tims::Address::make(host.settings.system, cls->class_id, static_cast<uint8_t>(instance));
      get(node, "autostart", s.autostart, "true or false");
      get_positive_ms(node, "retry_ms", s.retry_ns);
      get_positive_ms(node, "rpc_timeout_ms", s.rpc_timeout_ns);
      if (int64_t retries = 0; get_int_range(node, "rpc_retries", 0, 10, retries, "a number of retries 0..10")) {
        s.rpc_retries = static_cast<uint32_t>(retries);
      }

      std::unique_ptr<Component> component;
      try {
        component = cls->make();
      } catch (const std::exception& e) {
        error(node["class"].Mark(), "cannot construct '" + impl + "': " + e.what());
        continue;
      }
      // What GET_CLASS serves (tools learn the class from it), with the declared values
      // as defaults: before the host file's values are set below.
      try {
        component->class_description_ = encode_class_description(describe_class(*cls, component->parameters()),
                                                                 &component->class_description_base_);
      } catch (const std::exception& e) {
        error(node["class"].Mark(), "class '" + impl + "' cannot be described to tools: " + e.what());
        continue;
      }
      const DataTaskMode mode = component->data_task_mode();
      if (const YAML::Node ct = node["command_task"]) {
        if (!ct.IsMap()) error(ct.Mark(), "'command_task' must be a map (priority, cpu, stack_kib, slots)");
        else {
          read_task(ct, s.command_task, "command_task", {"slots"});
          int64_t slots = 0;
          if (get_int_range(ct, "slots", 1, 4096, slots, "a slot count"))
            s.command_slots = static_cast<uint32_t>(slots);
        }
      }
      const YAML::Node dt = node["data_task"];
      if (mode == DataTaskMode::kNone) {
        if (dt) error(dt.Mark(), "class '" + impl + "' has no data task");
      } else if (!dt) {
        if (mode == DataTaskMode::kPeriodic) {
          error(node.Mark(),
                "component '" + name + "': class '" + impl + "' has a periodic data task: give data_task.period_ms");
        }
      } else if (!dt.IsMap()) {
        error(dt.Mark(), "'data_task' must be a map");
      } else {
        std::set<std::string> extra{"ring", "max_listeners", "lease_ms"};
        if (mode == DataTaskMode::kPeriodic) extra.insert({"period_ms", "phase_ms"});
        else extra.insert({"timeout_ms", "input_slots"});
        read_task(dt, s.data_task, "data_task of a " + std::string(describe(mode)) + " class", extra, 0);
        int64_t n = 0;
        if (get_int_range(dt, "ring", 2, 1'000'000, n, "a sample count")) s.ring_size = static_cast<uint32_t>(n);
        if (get_int_range(dt, "max_listeners", 1, 1024, n, "a listener count"))
          s.max_listeners = static_cast<uint32_t>(n);
        if (get_int_range(dt, "lease_ms", 100, 86'400'000, n, "a lease of 100..86400000 ms")) {
          s.lease_ns = n * rt::kNsPerMs;
        }
        if (get_int_range(dt, "input_slots", 1, 4096, n, "a slot count")) s.input_slots = static_cast<uint32_t>(n);
        if (mode == DataTaskMode::kPeriodic) {
          if (!dt["period_ms"]) error(dt.Mark(), "periodic data task without 'period_ms'");
          else get_positive_ms(dt, "period_ms", s.period_ns);
          // Deadlines on a fixed grid of the clock: tasks of one host (or cyclictest
          // --secaligned) in a chosen phase against each other.
          if (double ms = 0; dt["phase_ms"] && get(dt, "phase_ms", ms, "a number of milliseconds")) {
            const auto ns = static_cast<int64_t>(std::llround(ms * 1e6));
            if (!(ms >= 0) || !std::isfinite(ms) || (s.period_ns > 0 && ns >= s.period_ns)) {
              error(dt["phase_ms"].Mark(),
                    "'phase_ms' = " + dt["phase_ms"].Scalar() + " must be at least 0 and below period_ms");
            } else {
              s.phase_ns = ns;
            }
          }
        } else {
          get_positive_ms(dt, "timeout_ms", s.data_timeout_ns);
        }
      }
      // data_task.timeout_ms of a class with declared inputs is the former name of its
      // parameter silence_ms (docs/parameters.md): taken there, with a warning.
      std::optional<std::pair<std::string, YAML::Node>> old_timeout;
      const auto* consumer = dynamic_cast<const DataComponentBase*>(component.get());
      if (dt && dt.IsMap() && dt["timeout_ms"] && consumer != nullptr && consumer->declares_inputs()) {
        old_timeout.emplace("timeout_ms", dt["timeout_ms"]);
      }
      // Parameters.
      Pending p{node, std::move(component), {}};
      ParameterSet& params = p.component->parameters();
      // Relative paths in parameters (declared defaults and the file's values) are the
      // host file's folder's.
      for (std::size_t i = 0; i < params.size(); ++i) {
        if (auto err = params.at(i).set_base_dir(base_dir)) error(node.Mark(), "component '" + name + "': " + *err);
      }
      std::set<std::string> given;
      std::map<const Parameter*, YAML::Mark> given_marks;
      if (const YAML::Node pn = node["params"]) {
        if (!pn.IsMap()) {
          error(pn.Mark(), "'params' must be a map of parameter: value");
        } else {
          for (auto it = pn.begin(); it != pn.end(); ++it) {
            const std::string key = it->first.Scalar();
            Parameter* param = params.find(key.c_str());
            if (param == nullptr && (param = params.renamed(key)) != nullptr) {
              warn(it->first.Mark(), "component '" + name + "': parameter '" + key + "' is now '" + param->name() +
                                         "' (the old name still works; rename it: docs/parameters.md)");
              if (pn[param->name()]) {
                error(it->first.Mark(), "component '" + name + "': '" + key + "' and '" + param->name() +
                                            "' are the same parameter (old and new name): give one");
                continue;
              }
            }
            if (param == nullptr) {
              error(it->first.Mark(),
                    "unknown parameter '" + key + "' for class '" + impl + "' (known: " + params.names() + ")");
              continue;
            }
            if (!it->second.IsScalar()) {
              error(it->second.Mark(), "parameter '" + key + "' must be a single value");
              continue;
            }
            if (auto err = param->set_from_text(it->second.Scalar())) {
              error(it->second.Mark(), *err);
              continue;
            }
            given.insert(param->name());
            given_marks[param] = it->second.Mark();
            if (param->spec().component_ref) p.refs.emplace_back(param, it->second);
          }
        }
      }
      if (old_timeout && given.count("silence_ms") == 0) {
        const YAML::Node v = old_timeout->second;
        warn(v.Mark(), "component '" + name +
                           "': data_task.timeout_ms is now the parameter silence_ms (params: {silence_ms: " +
                           v.Scalar() + "}; the old name still works: docs/parameters.md)");
        if (auto err = params.find("silence_ms")->set_from_text(v.Scalar())) error(v.Mark(), *err);
        else given_marks[params.find("silence_ms")] = v.Mark();
      }
      // The host's default log level for components that do not set their own.
      if (given.count(Component::kLogLevelParam) == 0) {
        if (Parameter* lp = params.find(Component::kLogLevelParam))
          (void)lp->set_from_text(gdos::describe(host.settings.gdos.level));
      }
      for (std::size_t i = 0; i < params.size(); ++i) {
        const Parameter& prm = params.at(i);
        if (prm.spec().required && given.count(prm.name()) == 0) {
          error(node.Mark(),
                "component '" + name + "': missing required parameter '" + prm.name() + "' (" + prm.spec().doc + ")");
        }
      }
      if (options.check_paths) check_parameter_paths(node, name, params, given_marks);
      // The class's own rules for its values (what init() and SET_PARAM check too).
      if (ParameterProblem problem; !p.component->check_parameters(ParameterValues(), problem)) {
        const auto at = problem.parameter != nullptr ? given_marks.find(problem.parameter) : given_marks.end();
        error(at != given_marks.end() ? at->second : node.Mark(),
              "component '" + name + "': parameter '" +
                  (problem.parameter != nullptr ? problem.parameter->name() : std::string("?")) + "': " + problem.text);
      }
      if (by_name.count(name) != 0) {
        error(node["name"].Mark(), "duplicate component name '" + name + "'");
        continue;
      }
      if (const auto it = by_address.find(s.address.raw()); it != by_address.end()) {
        error(node.Mark(), "component '" + name + "' has the address " + s.address.str() + " of component '" +
                               pending[it->second].component->name() + "' (give another 'instance')");
        continue;
      }
      p.component->settings_ = s;
      component_addresses[name] = s.address;
      by_name[name] = pending.size();
      by_address[s.address.raw()] = pending.size();
      pending.push_back(std::move(p));
    }

    // Resolve references; collect dependencies.
    std::vector<std::vector<std::size_t>> deps(pending.size());
    for (std::size_t i = 0; i < pending.size(); ++i) {
      for (auto& [param, vnode] : pending[i].refs) {
        const std::string target = param->get_string();
        tims::Address addr;
        if (const auto it = by_name.find(target); it != by_name.end()) {
          addr = pending[it->second].component->address();
          if (it->second == i) {
            error(vnode.Mark(), "component '" + pending[i].component->name() + "' depends on itself");
            continue;
          }
          if (!param->spec().weak_ref) deps[i].push_back(it->second);
        } else if (const auto parsed = tims::parse_address(target)) {
          addr = *parsed;
          if (const auto it2 = by_address.find(addr.component().raw());
              it2 != by_address.end() && !param->spec().weak_ref) {
            deps[i].push_back(it2->second);
          }
        } else {
          error(vnode.Mark(), "parameter '" + param->name() + "': no component named '" + target +
                                  "' in this host file (give a name or an address like Generator(0/1))");
          continue;
        }
        pending[i].component->refs_.emplace_back(param, addr.component());
      }
    }
    // Topological order: dependencies first; a cycle is an error.
    std::vector<int> mark(pending.size(), 0);
    std::vector<std::size_t> order;
    std::function<bool(std::size_t)> visit = [&](std::size_t i) {
      if (mark[i] == 2) return true;
      if (mark[i] == 1) {
        error(pending[i].node.Mark(), "dependency cycle through component '" + pending[i].component->name() + "'");
        return false;
      }
      mark[i] = 1;
      for (std::size_t d : deps[i]) {
        if (!visit(d)) return false;
      }
      mark[i] = 2;
      order.push_back(i);
      return true;
    };
    for (std::size_t i = 0; i < pending.size(); ++i) {
      if (!visit(i)) break;
    }
    if (!errors.empty()) return;
    std::vector<std::size_t> position(pending.size());
    for (std::size_t k = 0; k < order.size(); ++k) position[order[k]] = k;
    host.dependencies.assign(order.size(), {});
    for (std::size_t k = 0; k < order.size(); ++k) {
      for (std::size_t d : deps[order[k]]) host.dependencies[k].push_back(position[d]);
      host.components.push_back(std::move(pending[order[k]].component));
    }
  }
};

std::string host_file_folder(const std::string& file) {
  // Not canonical (symbolic links stay as the user named them); "" on an error of the
  // working directory: relative paths are then the process's.
  std::error_code ec;
  std::filesystem::path dir = std::filesystem::path(file).parent_path();
  if (dir.empty()) dir = ".";
  dir = std::filesystem::absolute(dir, ec);
  if (ec) return {};
  std::string out = dir.lexically_normal().string();
  while (out.size() > 1 && out.back() == '/') out.pop_back();
  return out;
}

LoadResult load_host_text(const std::string& text, const std::string& file, ComponentRegistry& registry,
                          const rt::RtCapabilities& caps, const HostLoadOptions& options) {
  HostLoader loader{file, registry, caps, options, {}, {}, {}, {}};
  // Outside input: whatever escapes the checks (a yaml-cpp conversion that throws, an
  // allocation that fails) is one more error of this file, never an exception.
  LoadResult r;
  try {
    r = loader.load(text);
  } catch (const std::exception& e) {
    r.host.reset();
    r.errors = loader.errors;
    r.errors.push_back({file, 0, 0, std::string("cannot load the host file: ") + e.what()});
  }
  // Messages quote the file's keys and values: they go to a terminal and a log as
  // clean text of bounded length, whatever the file held.
  for (auto& e : r.errors) e.message = clean_message(e.message);
  for (auto& w : r.warnings) w.message = clean_message(w.message);
  return r;
}

LoadResult load_host_file(const std::string& path, ComponentRegistry& registry, const rt::RtCapabilities& caps,
                          const HostLoadOptions& options) {
  std::string why;
  const auto text = read_host_bytes(path, why);
  if (!text) {
    LoadResult r;
    r.errors.push_back({path, 0, 0, why});
    return r;
  }
  return load_host_text(*text, path, registry, caps, options);
}

}  // namespace rack
