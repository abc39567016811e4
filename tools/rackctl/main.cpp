// rackctl: controls the components of running rackd executors over TiMS/LCM, as any
// other host would: it joins the LCM network as a tool (system kToolSystem), finds
// components by announcement (discovery) or by address, and sends RACK's generic
// messages (ON, OFF, GET_STATUS, GET_STATS, GET_LATENCY, GET_PARAM, SET_PARAM, GET_DATA,
// GET_CONT_DATA, STOP_CONT_DATA).
//
// A normal (non-RT) tool. It never hangs: every wait has a timeout.
//
// Exit codes: 0 ok, 1 the component answered ERROR (its reason is printed), 2 usage
// error, 3 not available (NOT_AVAILABLE reply, unknown name, no reply in time).
#include <dirent.h>
#include <fcntl.h>
#include <sched.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cstdarg>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "rack/client/deployment.h"
#include "rack/client/session.h"
#include "rack/core/class_description.h"
#include "rack/core/data_component.h"
#include "rack/core/host_config.h"
#include "rack/core/parameters.h"
#include "rack/core/payload_json.h"
#include "rack/core/trace_session.h"
#include "rack/core/wire.h"
#include "rack/rt/clock.h"
#include "rack/rt/latency_stats.h"
#include "rack/rt/output_file.h"
#include "rack/tims/address.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/link_auth.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/message.h"
#include "rack/tims/router.h"
#include "rack/tims/tool_address.h"
#include "rack/version.h"

#include "class_info.h"
#include "doctor.h"
#include "field_names.h"
#include "stream_stats.h"

namespace {

using rack::tims::Address;
using rack::tims::CallResult;
using rack::tims::CallStatus;
using rack::tims::ConstBuffer;
using rack::tims::MessageHeader;
namespace msg = rack::tims::msg;
namespace rt = rack::rt;
namespace tims = rack::tims;
namespace wire = rack::wire;

constexpr int kExitOk = 0;
constexpr int kExitError = 1;  // the component answered ERROR
constexpr int kExitUsage = 2;
constexpr int kExitUnavailable = 3;  // NOT_AVAILABLE, unknown name, timeout

// A command ends with this (thrown, so that the TiMS session shuts down on the way out).
struct Failure {
  int code;
  std::string message;
};
[[noreturn]] void fail(int code, std::string message) { throw Failure{code, std::move(message)}; }

// ---------------------------------------------------------------- help texts

constexpr const char* kUsage = R"(usage: rackctl [options] COMMAND [ARGS]

Controls the components of running rackd executors over TiMS/LCM.

commands:
  list [--json]                 every component that answers discovery, with its state
  classes [HOST] [--json]       the component classes running (on HOST) as they
                                describe themselves: data fields, commands, parameters
  hosts [--json]                every host that answers discovery: system, role, network
  on NAME                       switch a component on (answered when its on() finished)
  off NAME                      switch a component off
  status NAME [--json]          state and timing statistics (--json: one JSON object)
  latency NAME [--json]         the data task's wake-up latency histogram, overruns
  params NAME [--json]          the component's runtime parameters
  set-param NAME KEY VALUE      set one parameter (VALUE is parsed as the parameter's kind)
  get-data NAME [--time T]      one sample as a JSON line
  watch NAME [--period MS] [--count N]
                                continuous data, one JSON line per sample
  send NAME CMD [FIELD=VALUE ...] [--i64 N]
                                a class command (number 21..127 or its name, e.g.
                                INIT) with its body, and the reply
  hz NAME [--window N] [--period MS] [--count N] [--json]
                                rate of a data stream: min/max/mean/std of its period
  bw NAME [--window N] [--period MS] [--count N] [--json]
                                bandwidth of a data stream, message sizes
  doctor [--json]               check this host for real time (RT limits, memlock,
                                multicast route, rmem_max, PREEMPT_RT, ...), each
                                with the fix
  keygen FILE                   write a new TiMS link key file (mode 0600) for key_file
  threads [PID]                 where each thread of a rackd on this machine runs (CPUs,
                                scheduling): checks the host file's 'cpus:' partitioning
  trace --duration S --out FILE [--host HOST] [NAME ...|all]
                                record the task timeline of one host (Chrome JSON
                                trace: open it in ui.perfetto.dev or chrome://tracing)
  graph [--live] [--format dot|svg|json] [--out FILE] [--rackd PATH] FILE|DIR ...
                                the deployment of these host files as a graph:
                                hosts, components, tasks, data flows, networks
                                (--live: the flows that run too; without FILE,
                                what discovery finds)
  alloc [--live] [--json] [--rackd PATH] FILE|DIR ...
                                RT tasks per CPU of each host, priority
                                inversions flagged (--live: utilisation, latency;
                                without FILE, what runs: priorities and CPUs as
                                the tasks run, GET_TASKS)
  help [COMMAND]                this text, or a command's

NAME is a component's name from its host file (found by discovery), or an address
like Generator(0/0) (class, system/instance); the class may be any class a running
component describes (a plug-in's too: Counter(2/0)).

options:
  --lcm URL          TiMS/LCM network (default: $LCM_DEFAULT_URL, else
                     udpm://239.255.76.67:7667?ttl=0)
  --timeout MS       how long to wait for each reply (default 2000; at most a
                     day, 86400000, as --discover-ms)
  --retries N        ask again this often when no reply came in time (default 1;
                     a datagram on a network link can be lost)
  --discover-ms MS   how long to wait for announcements (default 300)
  --host-file FILE   join the network of this host file (the first of its
                     'tims: networks:', else its lcm_url) with that network's
                     key_file; --lcm and --key-file override either
  --key-file FILE    the network's key file (authenticated links: the file that
                     the host files name as key_file; default: $RACK_KEY_FILE);
                     without it, hosts whose network has a key drop what rackctl
                     sends
  -h, --help         this text; after a command: the command's help
  --version          the version (CMake project version, git describe)

exit codes: 0 ok, 1 the component answered ERROR, 2 usage error, 3 not available
(NOT_AVAILABLE, unknown name, or no reply within the timeout).

environment:
  RACK_TOOL_REGISTRY  the file where tools on this machine claim their TiMS address
                      (default /tmp/rack-tool-addresses.lock): every running rackctl
                      and rack-gui holds an address no other one holds
)";

struct Options {
  std::string lcm_url;
  std::string key_file;  // --key-file, else $RACK_KEY_FILE
  int64_t timeout_ms = 2000;
  int64_t discover_ms = 300;
  int64_t retries = 1;
  bool json = false;
  bool help = false;
  bool version = false;
  int64_t time_ns = 0;          // get-data --time
  double period_ms = 0.0;       // watch --period
  int64_t count = 0;            // watch --count (0: until SIGINT/SIGTERM); hz/bw: reports
  int64_t window = 0;           // hz/bw --window (0: the command's default)
  std::optional<int64_t> i64;   // send --i64: an 8-byte body
  double duration_s = 0.0;      // trace --duration
  std::string out;              // trace --out
  std::string host;             // trace --host
  std::string format = "dot";   // graph --format: dot | svg | json
  bool live = false;            // graph/alloc --live
  std::string rackd;            // graph/alloc --rackd: whose classes (default: beside rackctl)
  std::set<std::string> given;  // command-specific options seen (checked per command)
  std::string command;
  std::vector<std::string> args;
};

class Session;
struct Command {
  const char* name;
  const char* synopsis;
  std::size_t min_args;
  std::size_t max_args;
  std::set<std::string> options;  // command-specific options it accepts
  const char* help;
  int (*run)(Session&, const Options&);
};

// ---------------------------------------------------------------- small helpers

std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  char buf[1024];
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  return buf;
}

std::optional<int64_t> parse_int(const std::string& text) {
  int64_t v = 0;
  const char* first = text.data();
  const char* last = text.data() + text.size();
  if (first != last && *first == '+') ++first;
  const auto [ptr, ec] = std::from_chars(first, last, v);
  if (ec != std::errc() || ptr != last || first == last) return std::nullopt;
  return v;
}

std::optional<double> parse_double(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0])) != 0) return std::nullopt;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) return std::nullopt;
  return v;
}

// Shortest text that reads back as the same double.
std::string double_text(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, v);
  if (ec != std::errc()) return format("%.17g", v);
  return std::string(buf, ptr);
}

std::string quoted(const std::string& s) { return "\"" + rack::json_escape(s) + "\""; }

// What a user whose discovery found nothing can do (the first thing a new user meets
// when no rackd runs, or it runs on another network).
constexpr const char* kNoneAnsweredHint =
    ": is a rackd running on this network? (start one: rackd configs/demo.yaml; another network: --lcm URL or "
    "--host-file FILE; a slow one: --discover-ms MS)";

// A value from the command line or from the network as a message quotes it: its first
// `max` bytes, and its length when it is longer (a 100 kB argument, or a peer's
// megabyte-long text, is not echoed back whole).
constexpr std::size_t kShownBytes = 64;
std::string shown(const std::string& text, std::size_t max = kShownBytes) {
  if (text.size() <= max) return text;
  std::size_t cut = max;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;  // not inside a UTF-8 character
  return text.substr(0, cut) + "... (" + std::to_string(text.size()) + " bytes)";
}
// A whole message on stderr, at most 4 kB of it.
void print_failure(const std::string& message) { std::fprintf(stderr, "rackctl: %s\n", shown(message, 4096).c_str()); }

// Writes all of `n` bytes to `fd` (standard output). false with `error`.
bool write_all(int fd, const void* data, std::size_t n, std::string& error) {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t k = ::write(fd, p, n);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) {
      error = std::string("- (standard output): ") + (k < 0 ? std::strerror(errno) : "nothing written");
      return false;
    }
    p += k;
    n -= static_cast<std::size_t>(k);
  }
  return true;
}

using rack::client::error_reason;

const char* reply_name(int8_t type) {
  const char* n = msg::name(type);
  return n != nullptr ? n : "unknown reply";
}

// ---------------------------------------------------------------- the TiMS session

using rack::client::address_text;
using rack::client::default_lcm_url;

struct Target {
  Address address;
  std::string name;          // from the host file; empty when given as an address
  std::string class_name{};  // from its class description; empty: TiMS' name
  [[nodiscard]] std::string address_text() const { return ::address_text(address, class_name); }
  [[nodiscard]] std::string label() const { return name.empty() ? address_text() : name + " " + address_text(); }
};

rack::client::SessionConfig session_config(const Options& o) {
  rack::client::SessionConfig c;
  c.tool = "rackctl";
  c.lcm_url = o.lcm_url;
  c.key_file = o.key_file;
  c.timeout_ms = o.timeout_ms;
  c.retries = o.retries;
  c.discover_ms = o.discover_ms;
  return c;
}

// The client library's session (rack/client/session.h: tool mailboxes, discovery,
// class descriptions, requests, fan-out) with rackctl's way of ending a command:
// what cannot be resolved or answered fails with its exit code.
class Session : public rack::client::Session {
 public:
  explicit Session(const Options& o) : rack::client::Session(session_config(o)), options_(o) {}

  // The class name of `t`'s addresses from its description, when TiMS has no name
  // for its class id: every component class (rackctl is built with none). A
  // component that does not answer GET_CLASS at all would not answer the command's
  // request either (its command task answers both): that ends the command now,
  // after one wait, not two.
  void name_class(Target& t) {
    if (!t.class_name.empty() || tims::class_name(t.address.class_id()) != nullptr) return;
    if (const rack::ClassDescription* d = describe(t.address)) {
      t.class_name = d->class_name;
    } else if (class_unanswered(t.address)) {
      fail(kExitUnavailable, format("%s: no reply to GET_CLASS within %lld ms, %lld attempt(s) (is its rackd "
                                    "running on %s?)",
                                    t.label().c_str(), static_cast<long long>(options_.timeout_ms),
                                    static_cast<long long>(options_.retries + 1), url().c_str()));
    }
  }

  // NAME (host-file name) or address -> the component's command mailbox.
  Target resolve(const std::string& text) {
    if (const auto a = tims::parse_address(text)) {
      Target t{a->component(), "", ""};
      name_class(t);
      return t;
    }
    if (const auto named = rack::client::parse_named_address(text)) {
      // A class name TiMS does not know: the class whose description gives it, among
      // the components discovered at that system and instance.
      const auto& [cls, numeric] = *named;
      const auto found = find_by_class(cls, numeric.system(), numeric.instance());
      if (!found) {
        fail(kExitUnavailable, format("no component of a class named '%s' at system %u, instance %u answered "
                                      "discovery within %lld ms on %s (rackctl list shows the components that answer)",
                                      shown(cls).c_str(), numeric.system(), numeric.instance(),
                                      static_cast<long long>(options_.discover_ms), url().c_str()));
      }
      return Target{found->first.address.component(), "", found->second};
    }
    if (text.find('(') != std::string::npos) {
      fail(kExitUsage,
           "'" + shown(text) + "' is not an address (expected Class(system/instance), e.g. Generator(0/0))");
    }
    const auto found = find_component(text);
    if (!found) {
      fail(kExitUnavailable, format("no component named '%s' answered discovery within %lld ms on %s (rackctl list "
                                    "shows the components that answer)",
                                    shown(text).c_str(), static_cast<long long>(options_.discover_ms), url().c_str()));
    }
    Target t{found->address.component(), found->name, ""};
    name_class(t);
    return t;
  }

  // A request that must be answered; timeouts and NOT_AVAILABLE end the command
  // (exit 3). The result's body points into buffer() until the next call.
  using rack::client::Session::call;
  CallResult call(const Target& t, int8_t type, std::span<const ConstBuffer> body = {}) {
    const CallResult r = call(t.address, type, body);
    const char* what = msg::name(type) != nullptr ? msg::name(type) : "request";
    switch (r.status) {
      case CallStatus::kOk: break;
      case CallStatus::kTimeout:
        fail(kExitUnavailable,
             format("%s: no reply to %s within %lld ms, %lld attempt(s) (is its rackd running on %s?)",
                    t.label().c_str(), what, static_cast<long long>(options_.timeout_ms),
                    static_cast<long long>(options_.retries + 1), url().c_str()));
      default: fail(kExitUnavailable, t.label() + ": " + what + ": " + tims::describe(r.status));
    }
    if (r.reply.type == msg::kNotAvailable) {
      fail(kExitUnavailable, t.label() + ": NOT_AVAILABLE (no such component on a running host)");
    }
    return r;
  }
  template <typename T>
  CallResult call(const Target& t, int8_t type, const T& body) {
    const ConstBuffer part = tims::buffer_of(body);
    return call(t, type, std::span<const ConstBuffer>(&part, 1));
  }

  // Ends the command when the reply is ERROR (exit 1, its reason) or not `expected`.
  static void expect(const Target& t, const CallResult& r, int8_t expected, const char* what) {
    if (r.reply.type == expected) return;
    if (r.reply.type == msg::kError) fail(kExitError, t.label() + ": " + what + ": " + error_reason(r.body));
    fail(kExitError,
         format("%s: %s: unexpected reply %s (%d)", t.label().c_str(), what, reply_name(r.reply.type), r.reply.type));
  }

 private:
  const Options& options_;
};

// ---------------------------------------------------------------- commands

const char* state_name(int8_t reply_type) {
  switch (reply_type) {
    case msg::kEnabled: return "ENABLED";
    case msg::kDisabled: return "DISABLED";
    case msg::kError: return "ERROR";
    default: return "?";
  }
}

std::string class_label(const std::string& cls, const std::string& impl) {
  return impl.empty() ? cls : cls + "(" + impl + ")";
}

int cmd_list(Session& s, const Options& o) {
  struct Row {
    tims::ComponentInfo info;
    std::string host;
    std::string state = "no reply";
    std::string cls{};
  };
  const auto hosts = s.discover([](const std::vector<tims::HostInfo>&) { return false; });
  std::vector<Row> rows;
  for (const auto& h : hosts) {
    for (const auto& c : h.components)
      rows.push_back(Row{c, h.host + " (pid " + std::to_string(h.pid) + ")", "no reply"});
  }
  std::sort(rows.begin(), rows.end(),
            [](const Row& a, const Row& b) { return a.info.address.raw() < b.info.address.raw(); });
  if (rows.empty()) {
    fail(kExitUnavailable, format("no rackd answered discovery within %lld ms on %s%s",
                                  static_cast<long long>(o.discover_ms), s.url().c_str(), kNoneAnsweredHint));
  }
  // GET_STATUS to every component, a window of them at a time, each retried when
  // its reply did not come within --timeout (Session::fan_out).
  std::vector<Address> dests;
  for (const auto& r : rows) dests.push_back(r.info.address.component());
  std::size_t answered = 0;
  s.fan_out(dests, msg::kGetStatus, [&](std::size_t i, const MessageHeader& h) {
    rows[i].state = h.type == msg::kNotAvailable ? "NOT_AVAILABLE" : state_name(h.type);
    ++answered;
  });
  if (answered < rows.size()) {
    std::fprintf(stderr,
                 "rackctl: list: %zu of %zu component(s) did not answer GET_STATUS (%lld attempt(s) of %lld ms)\n",
                 rows.size() - answered, rows.size(), static_cast<long long>(o.retries + 1),
                 static_cast<long long>(o.timeout_ms));
  }
  // Class names from the descriptions (rackctl is built with no class), every class
  // at once (one shared deadline), asked of components that answered GET_STATUS: a
  // component that did not answer costs no second wait, and is named by its class
  // when another component of that class answered (else Class0xNN).
  std::vector<Address> answering;
  for (const auto& r : rows) {
    if (r.state != "no reply") answering.push_back(r.info.address.component());
  }
  s.describe_all(answering);
  for (auto& r : rows) {
    const rack::ClassDescription* d = s.described(r.info.address);
    const char* tims_name = tims::class_name(r.info.address.class_id());
    r.cls = tims_name != nullptr ? tims_name
            : d != nullptr       ? d->class_name
                                 : format("Class0x%02x", r.info.address.class_id());
  }
  if (o.json) {
    std::string out = "[";
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      out += (i == 0 ? "" : ",") + std::string("{\"address\":") + quoted(address_text(r.info.address, r.cls)) +
             ",\"name\":" + quoted(r.info.name) + ",\"class\":" + quoted(r.cls) + ",\"impl\":" + quoted(r.info.impl) +
             ",\"state\":" + quoted(r.state) + ",\"host\":" + quoted(r.host) + "}";
    }
    std::printf("%s]\n", out.c_str());
    return kExitOk;
  }
  std::printf("%-18s %-16s %-24s %-9s %s\n", "ADDRESS", "NAME", "CLASS(IMPL)", "STATE", "HOST");
  for (const auto& r : rows) {
    std::printf("%-18s %-16s %-24s %-9s %s\n", address_text(r.info.address, r.cls).c_str(), r.info.name.c_str(),
                class_label(r.cls, r.info.impl).c_str(), r.state.c_str(), r.host.c_str());
  }
  return kExitOk;
}

int cmd_hosts(Session& s, const Options& o) {
  auto hosts = s.discover([](const std::vector<tims::HostInfo>&) { return false; });
  if (hosts.empty()) {
    fail(kExitUnavailable, format("no host answered discovery within %lld ms on %s%s",
                                  static_cast<long long>(o.discover_ms), s.url().c_str(), kNoneAnsweredHint));
  }
  std::sort(hosts.begin(), hosts.end(), [](const tims::HostInfo& a, const tims::HostInfo& b) {
    return a.system != b.system ? a.system < b.system : a.host_id < b.host_id;
  });
  const int64_t now = rt::monotonic_ns();
  if (o.json) {
    std::string out = "[";
    for (std::size_t i = 0; i < hosts.size(); ++i) {
      const auto& h = hosts[i];
      out += (i == 0 ? "" : ",") + std::string("{\"host\":") + quoted(h.host) +
             ",\"system\":" + std::to_string(h.system) + ",\"host_id\":" + std::to_string(h.host_id) +
             ",\"role\":" + quoted(tims::describe(h.role)) + ",\"pid\":" + std::to_string(h.pid) +
             ",\"components\":" + std::to_string(h.components.size()) + ",\"network\":" + quoted(h.network) +
             ",\"seen_ms_ago\":" + std::to_string((now - h.last_seen_ns) / rt::kNsPerMs) + "}";
    }
    std::printf("%s]\n", out.c_str());
    return kExitOk;
  }
  std::printf("%-18s %-6s %-7s %-14s %-8s %-10s %-10s %s\n", "HOST", "SYSTEM", "HOST_ID", "ROLE", "PID", "COMPONENTS",
              "NETWORK", "SEEN");
  for (const auto& h : hosts) {
    std::printf("%-18s %-6u %-7u %-14s %-8d %-10zu %-10s %lld ms ago\n", h.host.c_str(), h.system, h.host_id,
                tims::describe(h.role), h.pid, h.components.size(), h.network.c_str(),
                static_cast<long long>((now - h.last_seen_ns) / rt::kNsPerMs));
  }
  return kExitOk;
}

int cmd_trace(Session& s, const Options& o) {
  namespace rtrace = rack::trace;
  if (o.duration_s <= 0) fail(kExitUsage, "trace needs --duration S (seconds, at most 60)");
  if (o.out.empty()) fail(kExitUsage, "trace needs --out FILE");
  std::vector<std::string> names;
  for (const auto& a : o.args) {
    for (auto& n : rtrace::split_names(a)) names.push_back(std::move(n));
  }
  const bool all = names.empty() || (names.size() == 1 && names[0] == "all");
  std::string joined;
  for (const auto& n : names) {
    if (n == "all" && names.size() > 1) fail(kExitUsage, "'all' traces every task: give it alone");
    joined += (joined.empty() ? "" : ",") + n;
  }
  rtrace::TraceStartRequest req;
  if (joined.size() >= sizeof req.names) fail(kExitUsage, "the names are too long (trace fewer, or all)");
  std::memcpy(req.names, joined.data(), joined.size());
  req.duration_ns = static_cast<int64_t>(o.duration_s * 1e9);
  if (req.duration_ns <= 0) fail(kExitUsage, "--duration is below a nanosecond");
  // The file is opened before anything is recorded: an unwritable --out (a missing
  // folder, a FIFO, a directory) is said at once, not after the trace. The chunks go to
  // a temporary file beside it as they come, so rackctl holds one chunk, not the trace;
  // it becomes FILE when the whole trace is there (rack/rt/output_file.h), and a trace
  // that fails leaves no FILE, whole or partial. '-': standard output.
  const bool to_stdout = o.out == "-";
  rt::OutputFile out;
  std::string out_error;
  if (!to_stdout && !out.open(o.out, "trace", rt::OutputMode::kReplace, out_error))
    fail(kExitUsage, "--out " + out_error + " (nothing recorded)");

  // Which host: the one with the named components, --host, or the only one there is.
  const auto holds = [&](const tims::HostInfo& h, const std::string& n) {
    return std::any_of(h.components.begin(), h.components.end(),
                       [&](const tims::ComponentInfo& c) { return c.name == n; });
  };
  const auto pick = [&](const std::vector<tims::HostInfo>& hosts) -> const tims::HostInfo* {
    for (const auto& h : hosts) {
      if (!o.host.empty() && h.host != o.host) continue;
      if (all || std::all_of(names.begin(), names.end(), [&](const std::string& n) { return holds(h, n); })) return &h;
    }
    return nullptr;
  };
  const auto hosts = s.discover(
      [&](const std::vector<tims::HostInfo>& hs) { return (!all || !o.host.empty()) && pick(hs) != nullptr; });
  if (all && o.host.empty() && hosts.size() > 1) {
    std::string list;
    for (const auto& h : hosts) list += (list.empty() ? "" : ", ") + h.host;
    fail(kExitUsage, "several hosts answered (" + list + "): say which with --host HOST, or name components");
  }
  const tims::HostInfo* host = pick(hosts);
  if (hosts.empty()) {
    fail(kExitUnavailable, format("no rackd answered discovery within %lld ms on %s%s",
                                  static_cast<long long>(o.discover_ms), s.url().c_str(), kNoneAnsweredHint));
  }
  if (host == nullptr) {
    std::string what = all ? "no host" : "no host with every component of '" + joined + "'";
    if (!o.host.empty()) what += " named '" + shown(o.host) + "'";
    fail(kExitUnavailable, format("%s answered discovery within %lld ms on %s (components on several hosts: trace "
                                  "each host on its own)",
                                  what.c_str(), static_cast<long long>(o.discover_ms), s.url().c_str()));
  }
  const Address exec = host->executor;
  const Target t{Address::make(exec.system(), exec.class_id(), exec.instance(), rtrace::kTraceMailbox),
                 "host '" + host->host + "' trace"};
  const std::string host_name = host->host;
  CallResult r = s.call(t, rtrace::kTraceStart, req);
  Session::expect(t, r, msg::kOk, "TRACE_START");
  rtrace::TraceStartReply started;
  if (r.body.size() != sizeof started) {
    fail(kExitError, format("%s (%s): TRACE_START reply of %zu bytes, expected %zu", t.label().c_str(),
                            r.reply.source().str().c_str(), r.body.size(), sizeof started));
  }
  std::memcpy(&started, r.body.data(), sizeof started);
  if (!tims::body_is_native(r.reply)) started.tasks = __builtin_bswap32(started.tasks);
  std::fprintf(stderr, "rackctl: recording %u task(s) of host '%s' for %.3f s\n", started.tasks, host_name.c_str(),
               o.duration_s);

  // Wait for the trace, then read it chunk by chunk, each written out as it comes. What
  // the peer says is bounded by what was asked: no more time left than the duration
  // asked for, no chunk longer than a TRACE_READ asks for (decode_chunk), no total over
  // kMaxTraceJsonBytes.
  uint64_t received = 0;
  uint64_t dropped = 0;
  const int64_t give_up = rt::monotonic_ns() + req.duration_ns + 30 * rt::kNsPerSec;
  uint64_t total = 0;
  for (;;) {
    if (rt::monotonic_ns() > give_up)
      fail(kExitUnavailable, t.label() + ": the trace was not ready 30 s after its end");
    rtrace::TraceReadRequest rr;
    rr.offset = received;
    r = s.call(t, rtrace::kTraceRead, rr);
    Session::expect(t, r, msg::kOk, "TRACE_READ");
    const rtrace::DecodedChunk chunk = rtrace::decode_chunk(r.body, !tims::body_is_native(r.reply), received, total);
    if (!chunk.ok) fail(kExitError, t.label() + " (" + r.reply.source().str() + "): " + chunk.error);
    const auto state = static_cast<rtrace::TraceState>(chunk.header.state);
    if (state == rtrace::TraceState::kRecording) {
      if (chunk.header.remaining_ns > req.duration_ns) {
        fail(kExitError,
             format("%s (%s): TRACE_READ says %lld ms are left of a trace of %lld ms", t.label().c_str(),
                    r.reply.source().str().c_str(), static_cast<long long>(chunk.header.remaining_ns / rt::kNsPerMs),
                    static_cast<long long>(req.duration_ns / rt::kNsPerMs)));
      }
      rt::sleep_for(std::clamp<int64_t>(chunk.header.remaining_ns, 10 * rt::kNsPerMs, 200 * rt::kNsPerMs));
      continue;
    }
    if (state != rtrace::TraceState::kReady)
      fail(kExitError, t.label() + ": the trace was discarded (see rackd's log)");
    const bool written = to_stdout ? write_all(STDOUT_FILENO, chunk.bytes.data(), chunk.bytes.size(), out_error)
                                   : out.write(chunk.bytes.data(), chunk.bytes.size(), out_error);
    if (!written) fail(kExitError, "--out " + out_error);
    received += chunk.bytes.size();
    dropped = chunk.header.dropped;
    total = chunk.header.total;
    if (received >= total) break;
  }
  if (!to_stdout && !out.commit(out_error)) fail(kExitError, "--out " + out_error);
  std::fprintf(to_stdout ? stderr : stdout, "%s: %llu bytes, %u task(s) of host '%s', %llu event(s) dropped\n",
               to_stdout ? "standard output" : o.out.c_str(), static_cast<unsigned long long>(received), started.tasks,
               host_name.c_str(), static_cast<unsigned long long>(dropped));
  return kExitOk;
}

int switch_command(Session& s, const Options& o, int8_t type) {
  const Target t = s.resolve(o.args[0]);
  const CallResult r = s.call(t, type);
  Session::expect(t, r, msg::kOk, type == msg::kOn ? "ON" : "OFF");
  std::printf("%s: %s\n", t.label().c_str(), type == msg::kOn ? "ENABLED" : "DISABLED");
  return kExitOk;
}
int cmd_on(Session& s, const Options& o) { return switch_command(s, o, msg::kOn); }
int cmd_off(Session& s, const Options& o) { return switch_command(s, o, msg::kOff); }

std::string us(int64_t ns) { return double_text(static_cast<double>(ns) / 1000.0); }

// The executor's latency statistics count everything from 10 ms on in one open bucket
// (rack/rt/latency_stats.h), whose percentiles come back as its upper edge, 10.001 ms:
// such a percentile is ">= 10 ms", not a measured 10001 us.
constexpr int64_t kOpenLatencyNs = static_cast<int64_t>(rt::LatencyStats::kBuckets - 1) * rt::LatencyStats::kBucketNs;
bool in_open_bucket(int64_t p_ns, int64_t max_ns) { return rack::tools::in_open_bucket(p_ns, max_ns, kOpenLatencyNs); }
// A latency for people: 3 significant digits and its unit ("37.0 us", "1.25 ms"); the
// JSON keeps the exact microseconds.
std::string latency_for_people(int64_t ns) { return rack::tools::seconds_text(static_cast<double>(ns) * 1e-9); }
// A percentile for people, or ">= 10 ms" in the open bucket.
std::string percentile_text(int64_t p_ns, int64_t max_ns) {
  return rack::tools::percentile_text(p_ns, max_ns, kOpenLatencyNs);
}
// JSON: the raw values stay; this names the percentiles that lie in the open bucket.
std::string open_bucket_json(int64_t p50, int64_t p99, int64_t p999, int64_t max_ns) {
  std::string list;
  const std::pair<const char*, int64_t> ps[] = {{"p50", p50}, {"p99", p99}, {"p99.9", p999}};
  for (const auto& [name, v] : ps) {
    if (in_open_bucket(v, max_ns)) list += (list.empty() ? "\"" : ",\"") + std::string(name) + "\"";
  }
  return ",\"open_bucket_from_us\":" + us(kOpenLatencyNs) + ",\"in_open_bucket\":[" + list + "]";
}

int cmd_status(Session& s, const Options& o) {
  const Target t = s.resolve(o.args[0]);
  const CallResult status = s.call(t, msg::kGetStatus);
  if (status.reply.type != msg::kEnabled && status.reply.type != msg::kDisabled && status.reply.type != msg::kError) {
    Session::expect(t, status, msg::kEnabled, "GET_STATUS");
  }
  const std::string state = state_name(status.reply.type);
  const CallResult r = s.call(t, msg::kGetStats);
  Session::expect(t, r, msg::kStats, "GET_STATS");
  wire::StatsReply st;
  if (!wire::read_payload(r.body, tims::body_is_native(r.reply), st)) {
    fail(kExitError,
         format("%s: GET_STATS: reply of %zu bytes, expected %zu", t.label().c_str(), r.body.size(), sizeof st));
  }
  const char* mode = rack::describe(static_cast<rack::DataTaskMode>(st.data_task));
  if (o.json) {
    std::string j = "{\"component\":" + quoted(t.address_text()) +
                    ",\"name\":" + (t.name.empty() ? std::string("null") : quoted(t.name)) +
                    ",\"state\":" + quoted(state) + ",\"data_task\":" + quoted(mode) +
                    ",\"period_ns\":" + std::to_string(st.period_ns) + ",\"cycles\":" + std::to_string(st.data.cycles) +
                    ",\"overruns\":" + std::to_string(st.data.overruns) +
                    ",\"latency_us\":{\"min\":" + us(st.data.latency_min_ns) +
                    ",\"p50\":" + us(st.data.latency_p50_ns) + ",\"p99\":" + us(st.data.latency_p99_ns) +
                    ",\"p99.9\":" + us(st.data.latency_p999_ns) + ",\"max\":" + us(st.data.latency_max_ns) +
                    ",\"mean\":" + us(st.data.latency_mean_ns) + ",\"samples\":" + std::to_string(st.data.samples) +
                    open_bucket_json(st.data.latency_p50_ns, st.data.latency_p99_ns, st.data.latency_p999_ns,
                                     st.data.latency_max_ns) +
                    "}" + ",\"execution_us\":{\"p50\":" + us(st.exec_p50_ns) + ",\"p99\":" + us(st.exec_p99_ns) +
                    ",\"max\":" + us(st.exec_max_ns) + ",\"samples\":" + std::to_string(st.exec_samples) + "}" +
                    ",\"published\":" + std::to_string(st.published) +
                    ",\"listeners\":" + std::to_string(st.listeners) +
                    ",\"listener_drops\":" + std::to_string(st.listener_drops) +
                    ",\"malformed\":" + std::to_string(st.malformed) + ",\"commands\":" + std::to_string(st.commands) +
                    ",\"errors\":" + std::to_string(st.errors) +
                    ",\"command_drops\":" + std::to_string(st.command_drops) +
                    ",\"page_faults_after_startup\":{\"command_task\":" +
                    ((st.faults_measured & 1) != 0 ? "{\"minor\":" + std::to_string(st.command_minor_faults) +
                                                         ",\"major\":" + std::to_string(st.command_major_faults) + "}"
                                                   : std::string("null")) +
                    ",\"data_task\":" +
                    ((st.faults_measured & 2) != 0 ? "{\"minor\":" + std::to_string(st.data_minor_faults) +
                                                         ",\"major\":" + std::to_string(st.data_major_faults) + "}"
                                                   : std::string("null")) +
                    "}" + ",\"access_denied\":" + std::to_string(st.access_denied) +
                    ",\"input_forged\":" + std::to_string(st.input_forged) +
                    ",\"input_requests\":" + std::to_string(st.input_requests) +
                    ",\"input_late\":" + std::to_string(st.input_late) +
                    ",\"listeners_expired\":" + std::to_string(st.listeners_expired) + ",\"error_reason\":" +
                    quoted(std::string(st.error_reason, strnlen(st.error_reason, sizeof st.error_reason))) + "}";
    std::printf("%s\n", j.c_str());
    return kExitOk;
  }
  std::printf("%s\n", t.label().c_str());
  std::printf("  %-16s %s\n", "state", state.c_str());
  if (st.error_reason[0] != '\0') {  // why it is in ERROR
    std::printf("  %-16s %.*s\n", "reason", static_cast<int>(strnlen(st.error_reason, sizeof st.error_reason)),
                st.error_reason);
  }
  if (st.period_ns > 0) {
    std::printf("  %-16s %s, period %s ms\n", "data task", mode,
                double_text(static_cast<double>(st.period_ns) / 1e6).c_str());
  } else {
    std::printf("  %-16s %s\n", "data task", mode);
  }
  const auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  std::printf("  %-16s %llu\n", "cycles", u(st.data.cycles));
  std::printf("  %-16s %llu\n", "overruns", u(st.data.overruns));
  if (st.data.samples > 0) {
    const int64_t max_ns = st.data.latency_max_ns;
    std::printf("  %-16s min %s, p50 %s, p99 %s, p99.9 %s, max %s (%llu samples)\n", "wake-up latency",
                latency_for_people(st.data.latency_min_ns).c_str(),
                percentile_text(st.data.latency_p50_ns, max_ns).c_str(),
                percentile_text(st.data.latency_p99_ns, max_ns).c_str(),
                percentile_text(st.data.latency_p999_ns, max_ns).c_str(), latency_for_people(max_ns).c_str(),
                u(st.data.samples));
  } else {
    std::printf("  %-16s none measured\n", "wake-up latency");
  }
  if (st.exec_samples > 0) {  // how long loop() ran: periodic and triggered tasks alike
    // 3 significant digits and a unit, as the latency line ("812 us", "1.25 ms").
    std::printf("  %-16s p50 %s, p99 %s, max %s (%llu cycles)\n", "execution time",
                latency_for_people(st.exec_p50_ns).c_str(), latency_for_people(st.exec_p99_ns).c_str(),
                latency_for_people(st.exec_max_ns).c_str(), u(st.exec_samples));
  } else {
    std::printf("  %-16s none measured\n", "execution time");
  }
  std::printf("  %-16s %llu\n", "published", u(st.published));
  std::printf("  %-16s %llu\n", "listeners", u(st.listeners));
  std::printf("  %-16s %llu\n", "listener drops", u(st.listener_drops));
  std::printf("  %-16s %llu\n", "leases expired", u(st.listeners_expired));
  std::printf("  %-16s %llu\n", "access denied", u(st.access_denied));
  // Refused by the data mailbox (not from a subscribed producer; requests sent into it).
  std::printf("  %-16s %llu forged, %llu requests, %llu late\n", "input refused", u(st.input_forged),
              u(st.input_requests), u(st.input_late));
  std::printf("  %-16s %llu\n", "malformed", u(st.malformed));
  std::printf("  %-16s %llu\n", "commands", u(st.commands));
  std::printf("  %-16s %llu\n", "errors", u(st.errors));
  std::printf("  %-16s %llu\n", "command drops", u(st.command_drops));
  // Since each task's start-up; 0 is the target for an RT task (sampled once a second).
  const auto faults = [&](bool measured, uint64_t minor, uint64_t major) {
    return measured ? format("%llu minor, %llu major", u(minor), u(major)) : std::string("not measured");
  };
  std::printf("  %-16s command task %s; data task %s\n", "page faults",
              faults((st.faults_measured & 1) != 0, st.command_minor_faults, st.command_major_faults).c_str(),
              faults((st.faults_measured & 2) != 0, st.data_minor_faults, st.data_major_faults).c_str());
  return kExitOk;
}

// A latency for a bucket label: "800 us", "1.2 ms", "10 ms".
std::string latency_text(int64_t ns) {
  if (ns < rt::kNsPerMs) return double_text(static_cast<double>(ns) / 1e3) + " us";
  return double_text(static_cast<double>(ns) / 1e6) + " ms";
}

int cmd_latency(Session& s, const Options& o) {
  const Target t = s.resolve(o.args[0]);
  const CallResult r = s.call(t, msg::kGetLatency);
  Session::expect(t, r, msg::kLatency, "GET_LATENCY");
  wire::LatencyHistogram h;
  if (!wire::read_payload(r.body, tims::body_is_native(r.reply), h)) {
    fail(kExitError,
         format("%s: GET_LATENCY: reply of %zu bytes, expected %zu", t.label().c_str(), r.body.size(), sizeof h));
  }
  if (const char* bad = wire::check_latency_histogram(h)) {
    fail(kExitError, format("%s: GET_LATENCY: malformed reply: %s", t.label().c_str(), bad));
  }
  const char* mode = rack::describe(static_cast<rack::DataTaskMode>(h.data_task));
  const std::size_t n = h.bucket_count;
  const auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  if (o.json) {
    std::string j = "{\"component\":" + quoted(t.address_text()) +
                    ",\"name\":" + (t.name.empty() ? std::string("null") : quoted(t.name)) +
                    ",\"data_task\":" + quoted(mode) + ",\"period_ns\":" + std::to_string(h.period_ns) +
                    ",\"cycles\":" + std::to_string(h.cycles) + ",\"overruns\":" + std::to_string(h.overruns) +
                    ",\"samples\":" + std::to_string(h.samples) + ",\"latency_us\":{\"min\":" + us(h.min_ns) +
                    ",\"p50\":" + us(h.p50_ns) + ",\"p99\":" + us(h.p99_ns) + ",\"p99.9\":" + us(h.p999_ns) +
                    ",\"max\":" + us(h.max_ns) + ",\"mean\":" + us(h.mean_ns) +
                    open_bucket_json(h.p50_ns, h.p99_ns, h.p999_ns, h.max_ns) + "},\"buckets\":[";
    for (std::size_t i = 0; i < n; ++i) {
      j += (i == 0 ? "" : ",") + std::string("{\"lower_ns\":") + std::to_string(h.lower_ns[i]) +
           ",\"upper_ns\":" + (i + 1 < n ? std::to_string(h.lower_ns[i + 1]) : std::string("null")) +
           ",\"count\":" + std::to_string(h.counts[i]) + "}";
    }
    std::printf("%s]}\n", j.c_str());
    return kExitOk;
  }
  std::printf("%s: wake-up latency of the data task (%s", t.label().c_str(), mode);
  if (h.period_ns > 0) std::printf(", period %s ms", double_text(static_cast<double>(h.period_ns) / 1e6).c_str());
  std::printf(")\n  %llu samples, %llu cycles, %llu overruns\n", u(h.samples), u(h.cycles), u(h.overruns));
  if (h.samples == 0) {
    std::printf("  none measured%s\n", h.data_task == 0 ? " (no data task)" : "");
    return kExitOk;
  }
  std::printf("  min %s, p50 %s, p99 %s, p99.9 %s, max %s, mean %s\n", latency_for_people(h.min_ns).c_str(),
              percentile_text(h.p50_ns, h.max_ns).c_str(), percentile_text(h.p99_ns, h.max_ns).c_str(),
              percentile_text(h.p999_ns, h.max_ns).c_str(), latency_for_people(h.max_ns).c_str(),
              latency_for_people(h.mean_ns).c_str());
  // The rows from the first to the last non-empty bucket; bars linear in the count
  // (a non-empty bucket gets at least one '#', so that a single overrun shows).
  std::size_t first = n, last = 0;
  uint64_t most = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (h.counts[i] == 0) continue;
    first = std::min(first, i);
    last = i;
    most = std::max(most, h.counts[i]);
  }
  constexpr int kBarWidth = 40;
  std::printf("  %-19s %12s %7s\n", "LATENCY", "COUNT", "%");
  for (std::size_t i = first; i <= last; ++i) {
    const std::string range = i + 1 < n ? latency_text(h.lower_ns[i]) + " - " + latency_text(h.lower_ns[i + 1])
                                        : ">= " + latency_text(h.lower_ns[i]);
    int bar = static_cast<int>(static_cast<double>(h.counts[i]) / static_cast<double>(most) * kBarWidth + 0.5);
    if (h.counts[i] > 0 && bar == 0) bar = 1;
    std::printf("  %-19s %12llu %7.3f %s\n", range.c_str(), u(h.counts[i]),
                100.0 * static_cast<double>(h.counts[i]) / static_cast<double>(h.samples),
                std::string(static_cast<std::size_t>(bar), '#').c_str());
  }
  return kExitOk;
}

std::string param_value(const wire::ParamRecord& p) {
  switch (static_cast<wire::ParamKind>(p.kind)) {
    case wire::ParamKind::kInt: return std::to_string(p.int_value);
    case wire::ParamKind::kFloat: return double_text(p.float_value);
    case wire::ParamKind::kBool: return p.int_value != 0 ? "true" : "false";
    case wire::ParamKind::kString: return std::string(p.string_value, strnlen(p.string_value, sizeof p.string_value));
  }
  return "?";
}
std::string param_name(const wire::ParamRecord& p) { return std::string(p.name, strnlen(p.name, sizeof p.name)); }

std::string limit_text(double v) { return std::isfinite(v) ? double_text(v) : (v > 0 ? "inf" : "-inf"); }

// A parameter's declaration in one line: its doc, then [range unit, choices, flags].
std::string parameter_spec_text(const rack::ParameterDescription& d) {
  std::string extra;
  const auto add = [&](const std::string& x) {
    if (!extra.empty()) extra += ", ";
    extra += x;
  };
  if (std::isfinite(d.min) || std::isfinite(d.max)) {
    add(limit_text(d.min) + ".." + limit_text(d.max) + (d.unit.empty() ? "" : " " + d.unit));
  }
  if (!d.choices.empty()) {
    std::string c;
    for (const auto& x : d.choices) {
      if (!c.empty()) c += '|';
      c += x;
    }
    add(c);
  }
  if (!d.default_value.empty()) add("default " + d.default_value);
  if ((d.flags & rack::ParameterDescription::kRequired) != 0) add("required");
  if ((d.flags & rack::ParameterDescription::kInitOnly) != 0) add("read at start only");
  return d.doc + (extra.empty() ? "" : " [" + extra + "]");
}

std::string parameter_spec_json(const rack::ParameterDescription& d) {
  std::string choices = "[";
  for (std::size_t i = 0; i < d.choices.size(); ++i) {
    if (i > 0) choices += ',';
    choices += quoted(d.choices[i]);
  }
  // Infinite limits are null (JSON has no infinity): unbounded.
  return "{\"doc\":" + quoted(d.doc) + ",\"unit\":" + quoted(d.unit) + ",\"min\":" + double_text(d.min) +
         ",\"max\":" + double_text(d.max) + ",\"default\":" + quoted(d.default_value) + ",\"choices\":" + choices +
         "],\"required\":" + ((d.flags & rack::ParameterDescription::kRequired) != 0 ? "true" : "false") +
         ",\"init_only\":" + ((d.flags & rack::ParameterDescription::kInitOnly) != 0 ? "true" : "false") + "}";
}

std::string type_text(const rack::TypeDescription& t) {
  std::string out = t.name + " (" + std::to_string(t.size) + " bytes):";
  for (const auto& f : t.fields) {
    out += " " + f.name + ":" + rack::describe(f.kind);
    if (f.count > 1) out += "[" + std::to_string(f.count) + "]";
    if (!f.unit.empty()) out += "(" + f.unit + ")";  // as declared: vx:f64(m/s)
  }
  return out;
}

// The units of a type's fields as a JSON object ({"vx":"m/s"}; {} when none).
std::string units_json(const rack::TypeDescription& t) {
  std::string out = "{";
  for (const auto& f : t.fields) {
    if (!f.unit.empty()) out += (out.size() > 1 ? "," : "") + quoted(f.name) + ":" + quoted(f.unit);
  }
  return out + "}";
}

// Every class running on the hosts discovered (or on HOST): what it describes.
int cmd_classes(Session& s, const Options& o) {
  const std::string only = o.args.empty() ? std::string() : o.args[0];
  const auto hosts = s.discover([](const std::vector<tims::HostInfo>&) { return false; });
  std::map<uint32_t, std::pair<Address, std::string>> seen;  // system | class -> a component, its host
  for (const auto& h : hosts) {
    if (!only.empty() && h.host != only) continue;
    for (const auto& c : h.components) seen.try_emplace(c.address.raw() & 0xFFFF0000u, c.address.component(), h.host);
  }
  if (seen.empty()) {
    fail(kExitUnavailable, only.empty()
                               ? format("no rackd answered discovery within %lld ms on %s%s",
                                        static_cast<long long>(o.discover_ms), s.url().c_str(), kNoneAnsweredHint)
                               : format("no host '%s' with components answered discovery within %lld ms on %s",
                                        only.c_str(), static_cast<long long>(o.discover_ms), s.url().c_str()));
  }
  std::vector<Address> components;
  for (const auto& [key, where] : seen) components.push_back(where.first);
  s.describe_all(components);  // every class at once: one deadline for those that do not answer
  std::string json = "[";
  std::size_t undescribed = 0;
  for (const auto& [key, where] : seen) {
    const rack::ClassDescription* d = s.describe(where.first);
    if (d == nullptr) {
      ++undescribed;
      continue;
    }
    if (o.json) {
      std::string cmds = "[", params = "[";
      for (const auto& c : d->commands) {
        cmds += (cmds.size() > 1 ? "," : "") + std::string("{\"name\":") + quoted(c.name) +
                ",\"type\":" + std::to_string(c.type) + ",\"summary\":" + quoted(c.summary) +
                ",\"body\":" + (c.body ? quoted(type_text(*c.body)) : std::string("null")) + "}";
      }
      for (const auto& p : d->parameters) {
        params += (params.size() > 1 ? "," : "") + std::string("{\"name\":") + quoted(p.name) +
                  ",\"kind\":" + quoted(rack::describe(p.kind)) + ",\"spec\":" + parameter_spec_json(p) + "}";
      }
      json += (json.size() > 1 ? "," : "") + std::string("{\"host\":") + quoted(where.second) +
              ",\"system\":" + std::to_string(where.first.system()) + ",\"class\":" + quoted(d->class_name) +
              ",\"impl\":" + quoted(d->impl) + ",\"class_id\":" + std::to_string(d->class_id) +
              ",\"summary\":" + quoted(d->summary) +
              ",\"data\":" + (d->data ? quoted(type_text(*d->data)) : std::string("null")) +
              ",\"units\":" + (d->data ? units_json(*d->data) : std::string("{}")) + ",\"commands\":" + cmds +
              "],\"parameters\":" + params + "]}";
      continue;
    }
    std::printf("%s(%s) class 0x%02x on %s (system %u): %s\n", d->class_name.c_str(), d->impl.c_str(), d->class_id,
                where.second.c_str(), where.first.system(), d->summary.c_str());
    std::printf("  data      %s\n", d->data ? type_text(*d->data).c_str() : "(none)");
    for (const auto& c : d->commands) {
      std::printf("  command   %s %d %s - %s\n", c.name.c_str(), c.type,
                  c.body ? type_text(*c.body).c_str() : "(no body)", c.summary.c_str());
    }
    for (const auto& p : d->parameters) {
      std::printf("  param     %-20s %-6s %s\n", p.name.c_str(), rack::describe(p.kind),
                  parameter_spec_text(p).c_str());
    }
  }
  if (o.json) std::printf("%s]\n", json.c_str());
  if (undescribed > 0) {
    std::fprintf(stderr, "rackctl: classes: %zu class(es) gave no description (see above)\n", undescribed);
    return kExitUnavailable;
  }
  return kExitOk;
}

int cmd_params(Session& s, const Options& o) {
  const Target t = s.resolve(o.args[0]);
  const CallResult r = s.call(t, msg::kGetParam);
  Session::expect(t, r, msg::kParam, "GET_PARAM");
  if (r.body.size() % sizeof(wire::ParamRecord) != 0) {
    fail(kExitError, format("%s: GET_PARAM: reply of %zu bytes is not a list of %zu-byte records", t.label().c_str(),
                            r.body.size(), sizeof(wire::ParamRecord)));
  }
  const bool native = tims::body_is_native(r.reply);
  std::vector<wire::ParamRecord> records(r.body.size() / sizeof(wire::ParamRecord));
  for (std::size_t i = 0; i < records.size(); ++i) {
    (void)wire::read_payload(r.body.subspan(i * sizeof(wire::ParamRecord), sizeof(wire::ParamRecord)), native,
                             records[i]);
  }
  // Docs, units and ranges from the class's description (GET_CLASS reuses the buffer
  // the records were read from: they are copies by now).
  const rack::ClassDescription* described = s.describe(t.address);
  const auto spec_of = [&](const wire::ParamRecord& p) -> const rack::ParameterDescription* {
    return described != nullptr ? described->find_parameter(param_name(p)) : nullptr;
  };
  if (o.json) {
    std::string j = "[";
    for (std::size_t i = 0; i < records.size(); ++i) {
      const auto& p = records[i];
      const auto kind = static_cast<wire::ParamKind>(p.kind);
      const std::string v = kind == wire::ParamKind::kString ? quoted(param_value(p)) : param_value(p);
      // "spec" (what the class declares) first: name, kind and value stay the
      // object's end, as before descriptions.
      j += i == 0 ? "{" : ",{";
      if (const rack::ParameterDescription* d = spec_of(p)) j += "\"spec\":" + parameter_spec_json(*d) + ",";
      j += "\"name\":" + quoted(param_name(p)) + ",\"kind\":" + quoted(rack::describe(kind)) + ",\"value\":" + v + "}";
    }
    std::printf("%s]\n", j.c_str());
    return kExitOk;
  }
  for (const auto& p : records) {
    std::string value = param_value(p);
    const rack::ParameterDescription* d = spec_of(p);
    if (d != nullptr && !d->unit.empty()) value += " " + d->unit;
    std::printf("%-20s %-6s %-20s%s%s\n", param_name(p).c_str(), rack::describe(static_cast<wire::ParamKind>(p.kind)),
                value.c_str(), (p.flags & 1u) != 0 ? " (component)" : "",
                d != nullptr ? ("  " + parameter_spec_text(*d)).c_str() : "");
  }
  return kExitOk;
}

int cmd_set_param(Session& s, const Options& o) {
  const std::string& key = o.args[1];
  const std::string& text = o.args[2];
  if (key.empty() || key.size() >= wire::kParamNameLen) {
    fail(kExitUsage,
         format("parameter name '%s' must be 1..%zu characters", shown(key).c_str(), wire::kParamNameLen - 1));
  }
  const Target t = s.resolve(o.args[0]);
  // Learn the parameter's kind first.
  wire::ParamName name;
  wire::copy_text(name.name, key.c_str());
  CallResult r = s.call(t, msg::kGetParam, name);
  Session::expect(t, r, msg::kParam, "GET_PARAM");
  wire::ParamRecord record;
  if (!wire::read_payload(r.body, tims::body_is_native(r.reply), record)) {
    fail(kExitError, format("%s: GET_PARAM %s: reply of %zu bytes is not one parameter record", t.label().c_str(),
                            key.c_str(), r.body.size()));
  }
  const auto kind = static_cast<wire::ParamKind>(record.kind);
  const auto bad = [&](const char* what) {
    return Failure{kExitUsage, format("'%s' is not %s (parameter '%s' of %s is a %s)", shown(text).c_str(), what,
                                      key.c_str(), t.label().c_str(), rack::describe(kind))};
  };
  switch (kind) {
    case wire::ParamKind::kInt: {
      const auto v = parse_int(text);
      if (!v) throw bad("an integer");
      record.int_value = *v;
      break;
    }
    case wire::ParamKind::kFloat: {
      const auto v = parse_double(text);
      if (!v) throw bad("a finite number");
      record.float_value = *v;
      break;
    }
    case wire::ParamKind::kBool:
      if (text == "true" || text == "1") record.int_value = 1;
      else if (text == "false" || text == "0") record.int_value = 0;
      else throw bad("a bool (true, false, 1 or 0)");
      break;
    case wire::ParamKind::kString:
      if (text.size() >= wire::kParamStringLen) {
        throw bad(format("a string of at most %zu characters", wire::kParamStringLen - 1).c_str());
      }
      std::memset(record.string_value, 0, sizeof record.string_value);
      wire::copy_text(record.string_value, text.c_str());
      break;
    default:
      fail(kExitError,
           format("%s: parameter '%s' has an unknown kind %u", t.label().c_str(), key.c_str(), record.kind));
  }
  // A former name (docs/parameters.md): GET_PARAM answered with the new name's record;
  // SET_PARAM goes by the name given, so that the component says so in its log, and its
  // OK carries the warning.
  const std::string now = param_name(record);
  wire::copy_text(record.name, key.c_str());
  r = s.call(t, msg::kSetParam, record);
  Session::expect(t, r, msg::kOk, "SET_PARAM");
  if (!r.body.empty())
    std::fprintf(stderr, "rackctl: %s: warning: %s\n", t.label().c_str(), error_reason(r.body).c_str());
  std::printf("%s: %s = %s\n", t.label().c_str(), now.c_str(), param_value(record).c_str());
  return kExitOk;
}

// One DATA body (SampleHeader + sample) as a JSON line.
// `d`: the class's description (nullptr or no data type: unknown, printed as hex).
// `wait_for_names` false (a stream): an address field of a class not described yet is
// printed as Class0xNN(s/i) and its description asked without waiting (describe_later;
// the stream's loop polls it), so that a component that does not answer GET_CLASS
// never holds up the samples.
std::string sample_json(Session& s, const Target& t, const rack::ClassDescription* d, const MessageHeader& h,
                        std::span<const std::byte> body, bool wait_for_names = true) {
  const rack::TypeDescription* type = d != nullptr && d->data ? &*d->data : nullptr;
  wire::SampleHeader sh;
  if (body.size() < sizeof sh || !wire::read_payload(body.first(sizeof sh), tims::body_is_native(h), sh)) {
    fail(kExitError, format("%s: DATA of %zu bytes is shorter than a sample header", t.label().c_str(), body.size()));
  }
  const auto sample = body.subspan(sizeof sh);
  std::string j = "{\"component\":" + quoted(t.address_text()) +
                  ",\"name\":" + (t.name.empty() ? std::string("null") : quoted(t.name)) +
                  ",\"time_ns\":" + std::to_string(sh.time_ns) + ",\"sequence\":" + std::to_string(sh.sequence);
  if (type != nullptr && type->size == sample.size()) {
    j += ",\"data\":" + rack::payload_to_json(type->field_table(), sample, tims::body_is_native(h));
    // Enum and address fields by name beside their raw values (field_names.h).
    // An address field names its component by the class that component describes
    // (GET_CLASS, once per class).
    const std::string names = rack::tools::field_names_json(
        d->value_names, type->field_table(), sample, tims::body_is_native(h), [&s, wait_for_names](Address a) {
          if (wait_for_names) return address_text(a, s.class_name(a));
          if (tims::class_name(a.class_id()) == nullptr && s.described(a) == nullptr) s.describe_later({a});
          return address_text(a, s.known_class_name(a));
        });
    if (!names.empty()) j += ",\"names\":" + names;
  } else {
    std::string hex;
    static constexpr char kDigits[] = "0123456789abcdef";
    for (const std::byte b : sample) {
      hex += kDigits[static_cast<unsigned>(b) >> 4];
      hex += kDigits[static_cast<unsigned>(b) & 0xFu];
    }
    j += ",\"data_hex\":\"" + hex + "\"";
  }
  return j + "}";
}

int cmd_get_data(Session& s, const Options& o) {
  const Target t = s.resolve(o.args[0]);
  wire::GetDataRequest req;
  req.time_ns = o.time_ns;
  const CallResult r = s.call(t, msg::kGetData, req);
  Session::expect(t, r, msg::kData, "GET_DATA");
  // The reply's body lives in the session's buffer, which GET_CLASS reuses: a copy.
  const MessageHeader reply = r.reply;
  const std::vector<std::byte> body(r.body.begin(), r.body.end());
  const rack::ClassDescription* d = s.describe(t.address);
  std::printf("%s\n", sample_json(s, t, d, reply, body).c_str());
  return kExitOk;
}

// watch: SIGINT/SIGTERM set this; the receive loop polls it.
std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop.store(true, std::memory_order_relaxed); }

// Subscribes to the data of `t` (GET_CONT_DATA into the session's data mailbox, at
// period_ms; 0: every sample), calls subscribed(reply) once, then
// sample(arrival_ns, header, body, message_bytes) for each DATA (false: stop) and
// tick(now) every 100 ms at most (false: stop). The subscription is a lease: renewed
// (GET_CONT_DATA again, answered into the data mailbox) every lease / 4, so that a
// killed rackctl frees its slot within one lease. Ends on SIGINT/SIGTERM (then
// STOP_CONT_DATA), the producer's ERROR (exit 1) or silence (exit 3): no sample for
// 5 s, or twice the period plus --timeout when that is longer.
template <typename Subscribed, typename Sample, typename Tick>
void stream_samples(Session& s, const Target& t, double period_ms, Subscribed subscribed, Sample sample, Tick tick) {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);  // a closed stdout ends the stream (the callers check), not the process
  tims::Mailbox& data = s.data_mailbox();
  wire::ContDataRequest req;
  req.period_ns = static_cast<int64_t>(std::llround(period_ms * 1e6));
  req.mailbox = data.address().raw();
  const CallResult r = s.call(t, msg::kGetContData, req);
  Session::expect(t, r, msg::kContData, "GET_CONT_DATA");
  wire::ContDataReply rep;
  if (!wire::read_payload(r.body, tims::body_is_native(r.reply), rep)) {
    fail(kExitError, t.label() + ": GET_CONT_DATA: malformed CONT_DATA reply");
  }
  subscribed(rep);
  const auto stop_cont_data = [&] {
    wire::StopContDataRequest stop;
    stop.mailbox = data.address().raw();
    const ConstBuffer part = tims::buffer_of(stop);
    // Best effort: the producer may be gone.
    (void)s.endpoint().call(t.address, msg::kStopContData, std::span<const ConstBuffer>(&part, 1), s.buffer(),
                            s.timeout_ns());
  };
  const int64_t silence_ns = std::max<int64_t>(5 * rt::kNsPerSec, 2 * rep.period_ns + s.timeout_ns());
  const int64_t renew_every = rep.lease_ns > 0 ? rep.lease_ns / 4 : 0;
  int64_t renew_at = rt::monotonic_ns() + renew_every;
  std::vector<std::byte> buf(data.slot_size());
  int64_t last_sample = rt::monotonic_ns();
  while (!g_stop.load(std::memory_order_relaxed)) {
    const int64_t now = rt::monotonic_ns();
    if (!tick(now)) break;
    if (renew_every > 0 && now >= renew_at) {
      const ConstBuffer part = tims::buffer_of(req);
      (void)s.endpoint().send(t.address, msg::kGetContData, std::span<const ConstBuffer>(&part, 1), data.address());
      renew_at = now + renew_every;
    }
    if (now - last_sample >= silence_ns) {
      stop_cont_data();
      fail(kExitUnavailable,
           format("%s: no sample for %lld s", t.label().c_str(), static_cast<long long>(silence_ns / rt::kNsPerSec)));
    }
    int64_t wait = std::min<int64_t>(100 * rt::kNsPerMs, silence_ns - (now - last_sample));
    if (renew_every > 0) wait = std::max<int64_t>(0, std::min(wait, renew_at - now));
    const auto got = data.receive(buf, wait);
    if (got.status != tims::RecvStatus::kOk) continue;
    if (got.header.source().component() != t.address) continue;  // a late message of someone else
    const auto body = std::span<const std::byte>(buf).subspan(sizeof(MessageHeader),
                                                              got.length - sizeof(MessageHeader));
    if (got.header.type == msg::kError) {
      // The producer left ENABLED and dropped us: no STOP_CONT_DATA needed.
      fail(kExitError, t.label() + ": " + error_reason(body));
    }
    if (got.header.type == msg::kEndOfStream) {
      // The producer's stream ended (a replay at the end of its log): nothing more comes.
      std::fprintf(stderr, "rackctl: %s: end of stream (no more samples)\n", t.label().c_str());
      break;
    }
    if (got.header.type != msg::kData) continue;
    last_sample = rt::monotonic_ns();
    if (!sample(last_sample, got.header, body, static_cast<std::size_t>(got.length))) break;
  }
  stop_cont_data();
}

int cmd_watch(Session& s, const Options& o) {
  const Target t = s.resolve(o.args[0]);
  // Its own class: asked before the subscription (no sample waits for it); when it
  // does not answer (said on stderr), the samples are printed raw (data_hex).
  const rack::ClassDescription* described = s.describe(t.address);
  if (described == nullptr) {
    std::fprintf(stderr, "rackctl: watch: %s: its class is not described: samples are printed as data_hex\n",
                 t.label().c_str());
  }
  int64_t received = 0;
  stream_samples(
      s, t, o.period_ms,
      [&](const wire::ContDataReply& rep) {
        std::fprintf(stderr, "rackctl: watching %s, period %s ms\n", t.label().c_str(),
                     rep.period_ns > 0 ? double_text(static_cast<double>(rep.period_ns) / 1e6).c_str() : "unknown");
      },
      [&](int64_t, const MessageHeader& h, std::span<const std::byte> body, std::size_t) {
        // Components its address fields name: described without waiting (see sample_json).
        const std::string line = sample_json(s, t, described, h, body, false);
        if (std::printf("%s\n", line.c_str()) < 0 || std::fflush(stdout) != 0) return false;  // stdout closed
        return !(o.count > 0 && ++received >= o.count);
      },
      [&](int64_t) {
        s.poll_descriptions();  // never waits; one that gives up says so on stderr
        return true;
      });
  return kExitOk;
}

// A class command, by number (21..127) or by the name the class gives it
// (rackctl help send lists them), with its body built from FIELD=VALUE arguments
// through the body's field table, or an 8-byte integer body (--i64).
int cmd_send(Session& s, const Options& o) {
  // A bad number is a usage error before anything goes on the network.
  const auto number = parse_int(o.args[1]);
  if (number && (*number < msg::kFirstClassCommand || *number > 127)) {
    fail(kExitUsage, "CMD must be a class command number " + std::to_string(msg::kFirstClassCommand) +
                         "..127 (generic commands have their own rackctl commands), got '" + shown(o.args[1]) + "'");
  }
  const Target t = s.resolve(o.args[0]);
  // The class's commands as it describes them (GET_CLASS).
  const rack::ClassDescription* described = s.describe(t.address);
  const rack::CommandDescription* info = nullptr;
  int8_t cmd = 0;
  if (number) {
    cmd = static_cast<int8_t>(*number);
    if (described != nullptr) {
      for (const auto& c : described->commands) {
        if (c.type == cmd) info = &c;
      }
    }
  } else {
    std::string upper = o.args[1];
    for (char& ch : upper) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
    std::string names;
    if (described != nullptr) {
      for (const auto& c : described->commands) {
        if (upper == c.name) info = &c;
        if (!names.empty()) names += ", ";
        names += c.name;
      }
    }
    if (info == nullptr) {
      fail(kExitUsage,
           format("%s: class %s has no command '%s' (%s)", t.label().c_str(),
                  described != nullptr ? described->class_name.c_str() : "(not described)", shown(o.args[1]).c_str(),
                  names.empty() ? "no named commands known: give the number" : ("known: " + names).c_str()));
    }
    cmd = info->type;
  }
  const auto fields_given = std::span<const std::string>(o.args).subspan(2);
  if (o.i64 && !fields_given.empty()) fail(kExitUsage, "send: give either --i64 or FIELD=VALUE arguments, not both");
  std::vector<std::byte> body;
  if (!fields_given.empty()) {
    if (info == nullptr || !info->body) {
      fail(kExitUsage, format("%s: command %s takes no fields%s", t.label().c_str(), o.args[1].c_str(),
                              info == nullptr ? " that its class describes (use --i64 or a named command)" : ""));
    }
    const std::vector<tims::FieldDesc> table = info->body->field_table();
    body.assign(info->body->size, std::byte{0});
    for (const std::string& arg : fields_given) {
      const auto eq = arg.find('=');
      if (eq == std::string::npos || eq == 0) fail(kExitUsage, "send: '" + shown(arg) + "' is not FIELD=VALUE");
      const std::string key = arg.substr(0, eq);
      const tims::FieldDesc* field = nullptr;
      std::string names;
      for (const auto& f : table) {
        if (key == f.name) field = &f;
        names += names.empty() ? f.name : std::string(", ") + f.name;
      }
      if (field == nullptr) {
        fail(kExitUsage, format("send %s: %s has no field '%s' (fields: %s)", info->name.c_str(),
                                info->body->name.c_str(), shown(key).c_str(), names.c_str()));
      }
      if (const std::string why = rack::set_field_from_text(*field, body, arg.substr(eq + 1)); !why.empty()) {
        fail(kExitUsage, format("send %s: field '%s': %s", info->name.c_str(), key.c_str(), why.c_str()));
      }
    }
    // Fields not given are 0: say what goes out, so that nothing is a silent default.
    std::fprintf(stderr, "rackctl: %s %s %s\n", t.label().c_str(), info->name.c_str(),
                 rack::payload_to_json(table, body, true).c_str());
  } else if (o.i64) {
    body.resize(sizeof(int64_t));
    std::memcpy(body.data(), &*o.i64, sizeof(int64_t));
  }
  const ConstBuffer part{body.data(), body.size()};
  const CallResult r = body.empty() ? s.call(t, cmd) : s.call(t, cmd, std::span<const ConstBuffer>(&part, 1));
  const std::string what = info != nullptr ? info->name : o.args[1];

  if (r.reply.type == msg::kError) fail(kExitError, t.label() + ": command " + what + ": " + error_reason(r.body));
  std::string hex;
  for (std::size_t k = 0; k < r.body.size() && k < 256; ++k) hex += format("%02x", static_cast<unsigned>(r.body[k]));
  std::printf("%s: %s (%d)%s%s\n", t.label().c_str(), reply_name(r.reply.type), r.reply.type,
              r.body.empty() ? "" : ", body ", hex.c_str());
  return kExitOk;
}

// ---------------------------------------------------------------- hz, bw, doctor

int rate_command(Session& s, const Options& o, bool bandwidth) {
  const Target t = s.resolve(o.args[0]);
  const auto window = static_cast<std::size_t>(o.window > 0 ? o.window : (bandwidth ? 100 : 1000));
  rack::tools::StreamStats stats(window);
  std::fprintf(stderr, "rackctl: %s of %s over the last %zu samples, a report a second (Ctrl-C ends)\n",
               bandwidth ? "bandwidth" : "rate", t.label().c_str(), window);
  int64_t reports = 0;
  int64_t next_report = rt::monotonic_ns() + rt::kNsPerSec;
  stream_samples(
      s, t, o.period_ms, [](const wire::ContDataReply&) {},
      [&](int64_t at, const MessageHeader&, std::span<const std::byte>, std::size_t bytes) {
        stats.add(at, bytes);
        return true;
      },
      [&](int64_t now) {
        if (now < next_report) return true;
        next_report += rt::kNsPerSec;
        if (next_report <= now) next_report = now + rt::kNsPerSec;  // after a stall
        const auto r = stats.report();
        const std::string line = !r          ? std::string(o.json ? "{\"samples\":0}" : "no two samples yet")
                                 : o.json    ? rack::tools::stream_json(*r)
                                 : bandwidth ? rack::tools::bw_line(*r)
                                             : rack::tools::hz_line(*r);
        if (std::printf("%s\n", line.c_str()) < 0 || std::fflush(stdout) != 0) {
          return false;  // stdout closed
        }
        return !(o.count > 0 && ++reports >= o.count);
      });
  return kExitOk;
}
int cmd_hz(Session& s, const Options& o) { return rate_command(s, o, false); }
int cmd_bw(Session& s, const Options& o) { return rate_command(s, o, true); }

// The multicast group of an LCM URL udpm://GROUP:PORT?...; empty when it has none.
std::string lcm_group(const std::string& url) {
  const std::string scheme = "udpm://";
  if (url.rfind(scheme, 0) != 0) return "";
  const std::string rest = url.substr(scheme.size());
  return rest.substr(0, rest.find_first_of(":?"));
}

int run_doctor_command(const Options& o) {
  rack::tools::DoctorInput in;
  const std::string url = o.lcm_url.empty() ? default_lcm_url() : o.lcm_url;
  if (const std::string g = lcm_group(url); !g.empty()) in.multicast_group = g;
  const auto checks = rack::tools::run_doctor(in);
  bool failed = false;
  for (const auto& c : checks) failed = failed || c.verdict == rack::tools::Verdict::kFail;
  if (o.json) std::printf("%s\n", rack::tools::doctor_json(checks).c_str());
  else std::fputs(rack::tools::format_doctor(checks).c_str(), stdout);
  return failed ? kExitError : kExitOk;
}

// ---------------------------------------------------------------- graph, alloc

// `text` to --out through a temporary file (rack/rt/output_file.h: a FIFO or directory
// is refused, a failed write leaves no file), or to standard output (none, or '-').
void write_output(const std::string& path, const std::string& text, const char* what) {
  std::string error;
  if (path.empty() || path == "-") {
    if (!write_all(STDOUT_FILENO, text.data(), text.size(), error)) fail(kExitError, error);
    return;
  }
  rt::OutputFile f;
  if (!f.open(path, what, rt::OutputMode::kReplace, error) || !f.write(text, error) || !f.commit(error))
    fail(kExitError, "--out " + error);
}

// The hosts discovery found, as a deployment without host files (graph/alloc --live
// with no FILE): each host with its components' names, classes and addresses, and
// whether each has a data task and its period (GET_STATS); no parameters, so every
// flow drawn is a live one (GET_LISTENERS). The tasks' priorities and CPUs start as not
// known (Host::tasks_known); live_view asks GET_TASKS and run_graph/run_alloc take
// what runs (rack::deploy::adopt_running). A component that does not answer it (an
// older rackd) stays not known, not shown as the defaults.
std::vector<rack::deploy::Host> discovered_hosts(Session& s) {
  std::vector<rack::deploy::Host> hosts;
  std::vector<Address> dests;
  std::vector<std::pair<std::size_t, std::size_t>> who;
  for (const auto& info : s.discover([](const std::vector<tims::HostInfo>&) { return false; })) {
    rack::deploy::Host h;
    h.file = "discovery on " + (info.network.empty() ? s.url() : info.network);
    h.host = info.host;
    h.system = info.system;
    h.host_id = info.host_id;
    h.role = tims::describe(info.role);
    h.tasks_known = false;
    for (const auto& ci : info.components) {
      rack::deploy::Component c;
      c.name = ci.name;
      c.impl = ci.impl;
      c.class_name = s.class_name(ci.address);
      c.instance = ci.address.instance();
      c.address = ci.address.component().raw();
      c.address_text = rack::client::address_text(ci.address.component(), c.class_name);
      c.command_task.priority = -1;  // not known (cpu: -1)
      c.data_task.priority = -1;
      dests.push_back(ci.address.component());
      who.emplace_back(hosts.size(), h.components.size());
      h.components.push_back(std::move(c));
    }
    hosts.push_back(std::move(h));
  }
  if (hosts.empty()) fail(kExitUnavailable, "no host answered discovery on " + s.url() + " (and no host files given)");
  s.fan_out(dests, msg::kGetStats, [&](std::size_t i, const MessageHeader& h, std::span<const std::byte> body) {
    wire::StatsReply st;
    if (h.type != msg::kStats || !wire::read_payload(body, tims::body_is_native(h), st)) return;
    auto& c = hosts[who[i].first].components[who[i].second];
    c.has_data_task = st.data_task != 0;
    c.period_ns = st.period_ns;
  });
  return hosts;
}

// The deployment the arguments name (host files and directories of them); none with
// --live: what discovery finds.
rack::deploy::Deployment read_deployment(const Options& o, Session* s) {
  if (o.args.empty()) {
    if (s == nullptr) fail(kExitUsage, o.command + ": give host files or directories (or --live: what runs)");
    return rack::deploy::build(discovered_hosts(*s));
  }
  std::vector<std::string> errors;
  const auto paths = rack::deploy::host_file_paths(o.args, errors);
  for (const auto& e : errors) std::fprintf(stderr, "rackctl: %s\n", e.c_str());
  if (paths.empty()) fail(kExitUsage, "no host files to read");
  std::vector<rack::deploy::Host> hosts;
  for (const auto& p : paths) hosts.push_back(rack::deploy::read_host(p));
  // The classes' component references, from the rackd beside rackctl (or --rackd).
  std::vector<rack::deploy::ClassInfo> classes;
  std::string why;
  const std::string rackd = o.rackd.empty() ? rack::tools::rackd_beside_me() : o.rackd;
  if (!rack::tools::classes_from_rackd(rackd, classes, why, 10000, paths)) {
    std::fprintf(stderr,
                 "rackctl: %s: cannot learn the classes (%s): every parameter naming a component is taken "
                 "for a flow\n",
                 o.command.c_str(), why.c_str());
    return rack::deploy::build(std::move(hosts));
  }
  return rack::deploy::build(std::move(hosts), &classes);
}

// What discovery and GET_STATS say of the deployment's hosts and components.
rack::deploy::Live live_view(Session& s, const rack::deploy::Deployment& d, const std::string& command) {
  rack::deploy::Live live;
  live.hosts.resize(d.hosts.size());
  live.tasks.resize(d.hosts.size());
  const auto found = s.discover([](const std::vector<tims::HostInfo>&) { return false; });
  const int64_t now = rt::monotonic_ns();
  std::vector<Address> dests;
  std::vector<std::pair<std::size_t, std::size_t>> who;
  for (std::size_t h = 0; h < d.hosts.size(); ++h) {
    const auto& host = d.hosts[h];
    for (const auto& info : found) {
      if (info.system == host.system && info.host_id == host.host_id && (host.host.empty() || info.host == host.host)) {
        live.hosts[h].answered = true;
        live.hosts[h].seen_ms_ago = (now - info.last_seen_ns) / rt::kNsPerMs;
      }
    }
    live.tasks[h].resize(host.components.size());
    for (std::size_t c = 0; c < host.components.size(); ++c) {
      live.tasks[h][c].state = "no reply";
      if (!host.components[c].address) continue;
      dests.push_back(Address(*host.components[c].address));
      who.emplace_back(h, c);
    }
  }
  // Who subscribes to whom (GET_LISTENERS): the data flows that run. A rackd from before
  // GET_LISTENERS answers ERROR: its flows stay unknown (neither running nor not).
  live.listeners_known.resize(d.hosts.size());
  for (std::size_t h = 0; h < d.hosts.size(); ++h) live.listeners_known[h].assign(d.hosts[h].components.size(), false);
  s.fan_out(dests, msg::kGetListeners, [&](std::size_t i, const MessageHeader& h, std::span<const std::byte> body) {
    if (h.type != msg::kListeners) return;
    const auto& [host, comp] = who[i];
    if (const char* bad = rack::deploy::add_listeners(d, host, comp, body, tims::body_is_native(h), live)) {
      std::fprintf(stderr, "rackctl: %s: %s: malformed LISTENERS reply (%zu bytes): %s\n", command.c_str(),
                   d.hosts[host].components[comp].name.c_str(), body.size(), bad);
    }
  });
  rack::deploy::match_live_flows(d, live);
  // How each component's tasks run and its host's networks (GET_TASKS). A rackd from
  // before GET_TASKS answers ERROR: its tasks stay as its host file says (or not known).
  s.fan_out(dests, msg::kGetTasks, [&](std::size_t i, const MessageHeader& h, std::span<const std::byte> body) {
    if (h.type != msg::kTasks) return;
    const auto& [host, comp] = who[i];
    if (const char* bad = rack::deploy::add_tasks(d, host, comp, body, tims::body_is_native(h), live)) {
      std::fprintf(stderr, "rackctl: %s: %s: malformed TASKS reply (%zu bytes): %s\n", command.c_str(),
                   d.hosts[host].components[comp].name.c_str(), body.size(), bad);
    }
  });
  s.fan_out(dests, msg::kGetStats, [&](std::size_t i, const MessageHeader& h, std::span<const std::byte> body) {
    auto& t = live.tasks[who[i].first][who[i].second];
    t.answered = true;
    if (h.type != msg::kStats) {
      t.state = h.type == msg::kNotAvailable ? "NOT_AVAILABLE" : state_name(h.type);
      return;
    }
    wire::StatsReply st;
    if (!wire::read_payload(body, tims::body_is_native(h), st)) {
      t.state = format("malformed STATS (%zu bytes)", body.size());
      return;
    }
    t.state = rack::describe(static_cast<rack::ComponentState>(st.state));
    t.period_ns = st.period_ns;
    if (st.exec_samples > 0) t.exec_p50_ns = st.exec_p50_ns;
    if (st.exec_samples > 0 && st.period_ns > 0) {
      t.utilisation = static_cast<double>(st.exec_p50_ns) / static_cast<double>(st.period_ns);
    }
    if (st.data.samples > 0) t.worst_latency_ns = st.data.latency_max_ns;
  });
  return live;
}

bool has_errors(const rack::deploy::Deployment& d) {
  for (const auto& h : d.hosts) {
    if (!h.errors.empty()) return true;
  }
  return !d.problems.empty();
}

// DOT through graphviz's dot into SVG, on stdout or into `out` (dot writes the
// temporary file of an OutputFile, which becomes `out` when dot succeeded).
int write_svg(const std::string& dot_text, const std::string& out_path) {
  const std::string out = out_path == "-" ? std::string() : out_path;
  rt::OutputFile svg;
  std::string error;
  if (!out.empty() && !svg.open(out, "graph", rt::OutputMode::kReplace, error)) fail(kExitError, "--out " + error);
  char tmp[] = "/tmp/rackctl-graph-XXXXXX";
  const int fd = ::mkstemp(tmp);
  if (fd < 0) fail(kExitError, std::string("graph: cannot make a temporary file: ") + std::strerror(errno));
  const bool written = ::write(fd, dot_text.data(), dot_text.size()) == static_cast<ssize_t>(dot_text.size());
  ::close(fd);
  int rc = -1;
  if (written) {
    std::fflush(stdout);
    const pid_t pid = ::fork();
    if (pid == 0) {
      if (out.empty()) ::execlp("dot", "dot", "-Tsvg", tmp, static_cast<char*>(nullptr));
      else ::execlp("dot", "dot", "-Tsvg", "-o", svg.temp_path().c_str(), tmp, static_cast<char*>(nullptr));
      ::_exit(127);
    }
    int status = 0;
    if (pid > 0 && ::waitpid(pid, &status, 0) == pid && WIFEXITED(status)) rc = WEXITSTATUS(status);
  }
  ::unlink(tmp);
  if (rc == 127) {
    fail(kExitUnavailable,
         "graph --format svg needs graphviz's dot (apt-get install graphviz); "
         "--format dot prints the DOT text");
  }
  if (rc != 0) fail(kExitError, "graph: dot did not make the SVG (exit " + std::to_string(rc) + ")");
  if (!out.empty() && !svg.commit(error)) fail(kExitError, "--out " + error);
  return kExitOk;
}

int run_graph(Session* s, const Options& o) {
  auto d = read_deployment(o, s);
  std::optional<rack::deploy::Live> live;
  if (s != nullptr) live = live_view(*s, d, o.command);
  if (live && o.args.empty()) rack::deploy::adopt_running(d, *live);  // no host file: what runs
  const rack::deploy::Live* lp = live ? &*live : nullptr;
  for (const auto& h : d.hosts) {
    for (const auto& e : h.errors) std::fprintf(stderr, "rackctl: graph: %s\n", e.str().c_str());
  }
  for (const auto& p : d.problems) std::fprintf(stderr, "rackctl: graph: %s\n", p.c_str());
  if (o.format == "json") {
    write_output(o.out, rack::deploy::to_json(d, lp) + "\n", "graph");
  } else if (o.format == "svg") {
    write_svg(rack::deploy::to_dot(d, lp), o.out);
  } else {
    write_output(o.out, rack::deploy::to_dot(d, lp), "graph");
  }
  return has_errors(d) ? kExitError : kExitOk;
}

int run_alloc(Session* s, const Options& o) {
  auto d = read_deployment(o, s);
  std::optional<rack::deploy::Live> live;
  if (s != nullptr) live = live_view(*s, d, o.command);
  if (live && o.args.empty()) rack::deploy::adopt_running(d, *live);  // no host file: what runs
  const rack::deploy::Live* lp = live ? &*live : nullptr;
  if (o.json) std::printf("%s\n", rack::deploy::to_json(d, lp).c_str());
  else std::fputs(rack::deploy::allocation_text(d, lp).c_str(), stdout);
  return has_errors(d) ? kExitError : kExitOk;
}

int cmd_graph(Session& s, const Options& o) { return run_graph(&s, o); }
int cmd_alloc(Session& s, const Options& o) { return run_alloc(&s, o); }

int cmd_help(Session&, const Options&);  // handled before a session exists

// threads [PID]: /proc only, no session.
std::string read_line_of(const std::string& path) {
  FILE* f = std::fopen(path.c_str(), "r");
  if (f == nullptr) return {};
  char buf[256] = {};
  const bool ok = std::fgets(buf, sizeof buf, f) != nullptr;
  std::fclose(f);
  if (!ok) return {};
  std::string s = buf;
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

std::vector<long> numeric_entries(const std::string& dir) {
  std::vector<long> out;
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return out;
  while (const dirent* e = readdir(d)) {
    char* end = nullptr;
    const long n = std::strtol(e->d_name, &end, 10);
    if (n > 0 && end != nullptr && *end == '\0') out.push_back(n);
  }
  closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

int cmd_threads(const Options& o) {
  std::vector<long> pids;
  if (!o.args.empty()) {
    const auto pid = parse_int(o.args[0]);
    if (!pid || *pid <= 0 || *pid > INT_MAX) {
      std::fprintf(stderr, "rackctl: threads: '%s' is not a process id\n", shown(o.args[0]).c_str());
      return kExitUsage;
    }
    pids.push_back(static_cast<long>(*pid));
  } else {
    for (const long p : numeric_entries("/proc")) {
      if (read_line_of("/proc/" + std::to_string(p) + "/comm") == "rackd") pids.push_back(p);
    }
    if (pids.empty()) {
      std::fprintf(stderr, "rackctl: threads: no rackd runs on this machine\n");
      return kExitUnavailable;
    }
  }
  for (const long pid : pids) {
    const std::string base = "/proc/" + std::to_string(pid) + "/task";
    const auto tids = numeric_entries(base);
    if (tids.empty()) {
      std::fprintf(stderr, "rackctl: threads: no process %ld (or %s is not readable)\n", pid, base.c_str());
      return kExitUnavailable;
    }
    std::printf("rackd %ld (%s): %zu threads\n%8s  %-15s  %-8s  %s\n", pid,
                read_line_of("/proc/" + std::to_string(pid) + "/comm").c_str(), tids.size(), "TID", "NAME", "SCHED",
                "CPUS");
    for (const long tid : tids) {
      const std::string dir = base + "/" + std::to_string(tid);
      std::string cpus = "?";
      if (FILE* f = std::fopen((dir + "/status").c_str(), "r")) {
        char line[512];
        while (std::fgets(line, sizeof line, f) != nullptr) {
          if (std::strncmp(line, "Cpus_allowed_list:", 18) == 0) {
            cpus = line + 18;
            cpus.erase(0, cpus.find_first_not_of(" \t"));
            while (!cpus.empty() && (cpus.back() == '\n' || cpus.back() == ' ')) cpus.pop_back();
          }
        }
        std::fclose(f);
      }
      const int policy = sched_getscheduler(static_cast<pid_t>(tid));
      sched_param param{};
      (void)sched_getparam(static_cast<pid_t>(tid), &param);
      const std::string sched = policy == SCHED_FIFO ? "FIFO " + std::to_string(param.sched_priority)
                                : policy == SCHED_RR ? "RR " + std::to_string(param.sched_priority)
                                : policy < 0         ? "?"
                                                     : "OTHER";
      std::printf("%8ld  %-15s  %-8s  %s\n", tid, read_line_of(dir + "/comm").c_str(), sched.c_str(), cpus.c_str());
    }
  }
  return kExitOk;
}

const std::vector<Command>& commands() {
  static const std::vector<Command> kCommands = {
      {"list",
       "list [--json]",
       0,
       0,
       {"--json"},
       "Discovers every rackd on the network (waits the full --discover-ms), asks each\n"
       "component for its state and prints ADDRESS NAME CLASS(IMPL) STATE HOST.\n"
       "The requests go out together, at most 24 outstanding; one not answered within\n"
       "--timeout is sent again (--retries times). STATE is ENABLED, DISABLED, ERROR,\n"
       "or 'no reply' when no attempt was answered (their number is printed on\n"
       "stderr). CLASS is the name each class describes itself with (GET_CLASS to one\n"
       "answering component per class, all at once, within one --timeout x attempts):\n"
       "rackctl is built with no class. A component that did not answer shows as\n"
       "Class0xNN unless another of its class did. --json prints one JSON array instead.",
       cmd_list},
      {"hosts",
       "hosts [--json]",
       0,
       0,
       {"--json"},
       "Discovers every host on the network (waits the full --discover-ms) and prints\n"
       "HOST SYSTEM HOST_ID ROLE PID COMPONENTS NETWORK SEEN: what each announced, on\n"
       "which of this tool's networks it was heard, and how long ago (ms). Routers pass\n"
       "on the announcements of the robots behind them.",
       cmd_hosts},
      {"on",
       "on NAME",
       1,
       1,
       {},
       "Switches the component on. The reply comes when its on() has finished, so\n"
       "this also switches on what it depends on (cascading ON). ERROR: exit 1.",
       cmd_on},
      {"off",
       "off NAME",
       1,
       1,
       {},
       "Switches the component off (answered at once). Its listeners get an ERROR\n"
       "message and are dropped.",
       cmd_off},
      {"status",
       "status NAME [--json]",
       1,
       1,
       {"--json"},
       "Prints the state and the timing statistics: data task mode and period,\n"
       "cycles, overruns, wake-up latency (min, p50, p99, p99.9, max: 3 digits with\n"
       "their unit; a percentile beyond the histogram's 10 ms as \">= 10.0 ms\"),\n"
       "execution time of loop() (p50, p99, max with units; triggered tasks too),\n"
       "samples published, listeners, listener drops, malformed requests, commands,\n"
       "and the page faults of the command and data task since their start-up (0 is\n"
       "the target for an RT task; counted once a second by the executor).\n"
       "--json prints the same as one JSON object (exact values in us; the\n"
       "percentiles in the open bucket listed in latency_us.in_open_bucket).",
       cmd_status},
      {"latency",
       "latency NAME [--json]",
       1,
       1,
       {"--json"},
       "Prints the data task's wake-up latency histogram (GET_LATENCY): samples,\n"
       "cycles, overruns, min/p50/p99/p99.9/max/mean, then one row per bucket from\n"
       "the first to the last non-empty one: its range, count, share of the samples\n"
       "and a bar (linear; at least one '#' for a non-empty bucket). Buckets: 1 us\n"
       "wide below 8 us, then 10 a decade (1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8) up to\n"
       "the last, open one (>= 10 ms; a percentile there prints as \">= 10.0 ms\"); the\n"
       "edges come with the reply. A component without a data task prints \"none\n"
       "measured\". --json prints one JSON object with every bucket as\n"
       "{\"lower_ns\",\"upper_ns\" (null: open),\"count\"}.\n"
       "  rackctl latency generator",
       cmd_latency},
      {"params",
       "params NAME [--json]",
       1,
       1,
       {"--json"},
       "Prints the component's runtime parameters, one per line: name, kind, value\n"
       "with its unit, then what its class declares: the one-line doc, [range and\n"
       "unit, choices, default, required, read at start only]. --json: one array of\n"
       "{spec: {doc, unit, min, max (null: unbounded), default, choices, required,\n"
       "init_only}, name, kind, value} (no spec when the class gives no description).",
       cmd_params},
      {"classes",
       "classes [HOST] [--json]",
       0,
       1,
       {"--json"},
       "Lists the component classes running on every host discovered (or on HOST, by\n"
       "its host name) as each class describes itself to tools (GET_CLASS): class\n"
       "name (the one in addresses) and implementation, TiMS class id, summary, data\n"
       "type with its fields and their units (vx:f64(m/s)), commands with their body\n"
       "fields, parameters with docs, units and ranges. rackctl needs no class\n"
       "compiled in: a plug-in class is listed, printed (get-data, watch), addressed\n"
       "(Counter(2/0)) and sent commands by name like a built-in one. --json: one JSON\n"
       "array (\"units\": the data fields' units by field name).",
       cmd_classes},
      {"set-param",
       "set-param NAME KEY VALUE",
       3,
       3,
       {},
       "Sets one runtime parameter. VALUE is parsed as the parameter's kind (int,\n"
       "float, bool as true|false|1|0, string); a value that does not parse is a\n"
       "usage error (exit 2). The component's refusal (unknown parameter, out of\n"
       "range) is printed with exit 1. A parameter's former name (docs/parameters.md)\n"
       "still works: the new name is set, and a warning on stderr names it.",
       cmd_set_param},
      {"get-data",
       "get-data NAME [--time T]",
       1,
       1,
       {"--time"},
       "Prints one sample as a JSON line:\n"
       "  {\"component\":...,\"name\":...,\"time_ns\":...,\"sequence\":...,\"data\":{...}}\n"
       "--time T: the sample nearest host time T (ns); default 0 = the newest.\n"
       "The field names come from the class's description (GET_CLASS); a component\n"
       "that gives none (an older rackd) prints \"data_hex\" instead.",
       cmd_get_data},
      {"watch",
       "watch NAME [--period MS] [--count N]",
       1,
       1,
       {"--period", "--count"},
       "Subscribes (GET_CONT_DATA) and prints one JSON line per sample (as get-data).\n"
       "--period MS: the wanted period, 0..86400000 (the producer sends every n-th\n"
       "sample; the real period is printed on stderr); default 0 = every sample.\n"
       "--count N: stop after N samples. SIGINT/SIGTERM stop it too (exit 0). The\n"
       "producer going off: exit 1.\n"
       "The producer's stream ending (a replay at the end of its log): exit 0.\n"
       "No sample for 5 s: exit 3. The subscription is a lease (the producer's\n"
       "lease_ms): renewed every lease / 4, so a killed watch frees its slot in time.\n"
       "Address fields name the component by its class (GET_CLASS, asked without\n"
       "holding up the samples): Class0xNN(s/i) until the description arrives, and\n"
       "for good when that component does not answer within --timeout x attempts\n"
       "(said once on stderr); the watch goes on either way.",
       cmd_watch},
      {"send",
       "send NAME CMD [FIELD=VALUE ...] [--i64 N]",
       2,
       66,
       {"--i64"},
       "Sends class command CMD, a number from 21 to 127 or the command's name (as the\n"
       "class describes it: rackctl classes lists them), and prints the\n"
       "reply type and body (hex). FIELD=VALUE arguments fill the command's body:\n"
       "numbers, true|false, arrays as comma lists (x=1,2.5,4), addresses as 0x...;\n"
       "fields not given are 0 (the body sent is printed on stderr). A value that does\n"
       "not fit its field is a usage error (exit 2). --i64 N: an 8-byte integer body.\n"
       "ERROR: its reason, exit 1; no reply within --timeout: exit 3.\n"
       "  rackctl send mcl INIT x=2 y=1.5 phi=0 sigma_xy=0.3 sigma_phi=0.2\n"
       "  rackctl send pilot SET_DESTINATION x=4 y=2",
       cmd_send},
      {"hz",
       "hz NAME [--window N] [--period MS] [--count N] [--json]",
       1,
       1,
       {"--window", "--period", "--count", "--json"},
       "Subscribes like watch and prints, once a second, the rate of the stream and\n"
       "min/max/mean/std of the period between samples over the last N samples\n"
       "(--window, default 1000), like ros2 topic hz. Times are rackctl's arrival\n"
       "times, so network jitter counts. --period MS asks the producer for every n-th\n"
       "sample (as watch). --count N: stop after N reports (default: until\n"
       "SIGINT/SIGTERM, exit 0). --json: one JSON object per report (SI units).\n"
       "No sample for 5 s: exit 3; the producer going off: exit 1.\n"
       "  rackctl hz generator\n"
       "  rate 100 Hz  period min 8.02 ms, max 11.0 ms, mean 10.0 ms, std 244 us  (window 101 samples)",
       cmd_hz},
      {"bw",
       "bw NAME [--window N] [--period MS] [--count N] [--json]",
       1,
       1,
       {"--window", "--period", "--count", "--json"},
       "Subscribes like watch and prints, once a second, the bandwidth of the stream\n"
       "(bytes of its TiMS messages, header and sample, per second) and the mean, min\n"
       "and max message size over the last N samples (--window, default 100), like\n"
       "ros2 topic bw. Options as for hz.\n"
       "  rackctl bw generator\n"
       "  bandwidth 4.69 KiB/s  message mean 48 B, min 48 B, max 48 B  (window 100 samples)",
       cmd_bw},
      {"doctor",
       "doctor [--json]",
       0,
       0,
       {"--json"},
       "Checks what this host needs to run rackd in real time and prints one line per\n"
       "check (ok, WARN or FAIL), what it found, and for each problem the fix:\n"
       "  rt-priority      ulimit -r (RLIMIT_RTPRIO) or CAP_SYS_NICE: SCHED_FIFO tasks\n"
       "  memlock          ulimit -l unlimited or CAP_IPC_LOCK: mlockall\n"
       "  multicast-route  a route for the LCM group (of --lcm) on an interface that is up\n"
       "                   and multicast-capable\n"
       "  rmem-max         net.core.rmem_max >= 2 MiB (LCM's advice; large samples)\n"
       "  preempt-rt       a PREEMPT_RT kernel (/sys/kernel/realtime, /proc/version)\n"
       "  cpu-dma-latency  /dev/cpu_dma_latency writable (rackd's cpu_dma_latency_us)\n"
       "  clocksource      a clock read through the vDSO (tsc, kvm-clock, arch_sys_counter)\n"
       "It reads /proc, /sys and /dev only and changes nothing. Exit 0 when nothing\n"
       "FAILs (WARNs are allowed), 1 otherwise. --json: one JSON array.",
       cmd_help},
      {"threads",
       "threads [PID]",
       0,
       1,
       {},
       "Prints every thread of the rackd with process id PID (default: every rackd\n"
       "running on this machine) from /proc: TID NAME SCHED CPUS, where SCHED is\n"
       "FIFO/RR with the priority or OTHER, and CPUS the CPUs it may run on. With the\n"
       "host file's 'cpus:' block the RT tasks show the 'rt' CPUs and every other\n"
       "thread the 'housekeeping' ones (rackd prints the same table at start). Local:\n"
       "reads /proc, needs no network. Exit 3 when no such rackd runs.",
       cmd_help},
      {"keygen",
       "keygen FILE",
       1,
       1,
       {},
       "Writes a new key file for authenticated TiMS links: one random 32-byte key as\n"
       "64 hex digits, mode 0600; an existing file is never overwritten, and a write\n"
       "that fails (disk full) leaves no file. Copy it to\n"
       "every host of the network (keeping mode 0600) and name it in the host files\n"
       "(tims: networks: - key_file: PATH); tools take it with --key-file. Rotation:\n"
       "a file may hold two keys (two lines): the first signs, both are accepted;\n"
       "hosts re-read a changed file within a second. See the README.",
       cmd_help},
      {"trace",
       "trace --duration S --out FILE [--host HOST] [NAME ...|all]",
       0,
       64,
       {"--duration", "--out", "--host"},
       "Records the task timeline of one host for S seconds (at most 60) and writes it\n"
       "to FILE as a Chrome JSON trace, which ui.perfetto.dev and chrome://tracing\n"
       "open: one track per task (\"mcl data task\"), a slice per cycle (\"loop\" or\n"
       "\"command\", with its wake-up latency), instant events for wake-ups, overruns,\n"
       "mode switches and every message sent or received (with the peer address), and\n"
       "flow arrows from a send to the receive of the same message on that host.\n"
       "NAMEs (or comma lists) pick components, all on one host; 'all' or none: every\n"
       "task of the host (--host HOST when several answer discovery). rackd records\n"
       "into preallocated per-task rings and sends the trace back over TiMS in\n"
       "chunks, so this works from another machine. A ring that fills between two\n"
       "drains (10 ms) drops events: the count is printed and kept in the file\n"
       "(otherData.dropped_events); the host file's trace_ring_events sets the\n"
       "rings' size (4096). A trace already running: exit 1. FILE is opened\n"
       "before the trace starts: one that cannot be written (a missing folder; a FIFO,\n"
       "directory or device) is exit 2, with nothing recorded; '-' is standard output.\n"
       "The chunks go to a temporary file beside FILE, which becomes FILE once the\n"
       "trace is whole: a failed trace leaves none. A reply that is not a well-formed\n"
       "chunk of the trace (truncated, at another offset, a chunk over 32 KiB, a size\n"
       "over 1 GiB, more time left than asked for) is exit 1, with the byte it is wrong at.\n"
       "  rackctl trace --duration 2 --out sim.json all\n"
       "  rackctl trace --duration 5 --out mcl.json mcl,ladar",
       cmd_trace},
      {"graph",
       "graph [--live] [--format dot|svg|json] [--out FILE] [--rackd PATH] FILE|DIR ...",
       0,
       256,
       {"--live", "--format", "--out", "--rackd"},
       "Draws a deployment from its host files (a directory: its *.yaml files): a\n"
       "cluster per system (robot) and host with its role and networks, a box per\n"
       "component (name, address, class, each task's priority, CPU and period) and an\n"
       "arrow per data flow from producer to consumer, labelled with the consumer's\n"
       "parameter, the producer's period and the networks the flow crosses (blue;\n"
       "thick when it goes through system routers). A flow is a parameter that its\n"
       "class declares as a component reference (the rackd beside rackctl, or\n"
       "--rackd PATH, lists its classes as JSON, with the plug-in classes the files\n"
       "name loaded from their plugins: directories) whose value names a component of\n"
       "the same file or is an address like Generator(1/0); an address\n"
       "no given file places is a dashed box. Errors of the reader are red\n"
       "notes with file:line:col (the full validation is rackd's own check); exit 1 then.\n"
       "--live adds what the network says: hosts that did not answer discovery are\n"
       "grey and dashed (STALE), each component its state, utilisation (execution\n"
       "p50 / period) and worst wake-up latency (GET_STATS), and the data flows that\n"
       "run: each producer's subscribers (GET_LISTENERS). A file's flow that does not\n"
       "run is grey and dotted ('not running'), one that runs says 'running'; a\n"
       "subscription no file declares is green ('live only', with its period), to\n"
       "its listener's box (a tool's, e.g. a 'rackctl watch', when no file places it).\n"
       "--live without FILE draws the deployment as it runs, from discovery alone:\n"
       "every host and component that answers, each task's priority, CPUs and period\n"
       "as the kernel runs them (GET_TASKS), each running subscription as a flow\n"
       "('subscribed', the period its consumer gets) with the networks it crosses\n"
       "(the hosts' networks, from GET_TASKS). Offline it needs no network.\n"
       "--format svg runs graphviz's dot (apt-get install graphviz). --out FILE is\n"
       "written whole or not at all (a FIFO or directory is refused); '-' or none:\n"
       "standard output.\n"
       "  rackctl graph configs/two_robots/ | dot -Tsvg > fleet.svg\n"
       "  rackctl graph --live --format svg --out now.svg\n"
       "  rackctl graph --format svg --out fleet.svg configs/two_robots/",
       cmd_graph},
      {"alloc",
       "alloc [--live] [--json] [--rackd PATH] FILE|DIR ...",
       0,
       256,
       {"--live", "--json", "--rackd"},
       "Prints the allocation at a glance: per host and CPU (a task's 'cpu:', else the\n"
       "host's 'cpus: rt:', else 'any cpu') the RT tasks there (priority > 0), highest\n"
       "first, with their periods, and flags configuration priority inversions with\n"
       "'!': a consumer's data task above its producer's on one CPU, and two data\n"
       "tasks with the same priority on one CPU. --live adds each data task's\n"
       "measured utilisation (execution p50 / period), worst wake-up latency and\n"
       "state, the interval its loop() runs at (RUNS EVERY), marks hosts that did not\n"
       "answer discovery as STALE, and flags a task that does not run at the priority\n"
       "or on the CPU its host file says (GET_TASKS: RT refused, chrt, taskset).\n"
       "--live without FILE lists what runs, from discovery alone: every task with\n"
       "its priority and CPUs as the kernel runs them, and the inversions among them\n"
       "(a consumer above its producer through a running subscription); a component\n"
       "of an older rackd (no GET_TASKS) shows priority '?', 'not known'. --json: the\n"
       "deployment as one JSON object (what 'graph --format json' prints; a priority\n"
       "or cpu not known is null). Exit 1 when a host file has errors.",
       cmd_alloc},
      {"help", "help [COMMAND]", 0, 1, {}, "Prints the usage, or a command's help.", cmd_help},
  };
  return kCommands;
}

const Command* find_command(const std::string& name) {
  for (const auto& c : commands()) {
    if (name == c.name) return &c;
  }
  return nullptr;
}

void print_command_help(const Command& c, FILE* out) {
  std::fprintf(out, "usage: rackctl [options] %s\n\n%s\n", c.synopsis, c.help);
  if (std::string(c.name) == "send") {
    std::fprintf(out,
                 "\nEach class describes its commands (names, numbers, body fields) to rackctl:\n"
                 "'rackctl classes [HOST]' lists them for the classes running there.\n");
  }
  std::fprintf(out, "\n(rackctl --help for the common options)\n");
}

int cmd_help(Session&, const Options&) { return kExitOk; }

// ---------------------------------------------------------------- arguments

// Longest wait an option may ask for: 9223372036854775807 ms overflowed the deadline in
// ns (undefined behaviour; discovery gave up at once, saying it had waited that long).
constexpr int64_t kMaxWaitMs = 86'400'000;

bool looks_like_option(const std::string& a) {
  if (a.size() < 2 || a[0] != '-') return false;
  // "-5" and "-.5" are values (set-param NAME KEY -5), not options.
  return !(std::isdigit(static_cast<unsigned char>(a[1])) != 0 || a[1] == '.');
}

Options parse_arguments(int argc, char** argv) {
  Options o;
  if (const char* env = std::getenv("RACK_KEY_FILE"); env != nullptr) o.key_file = env;
  std::string host_file;
  bool key_given = false;
  bool only_positional = false;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (only_positional || !looks_like_option(a)) {
      if (o.command.empty()) o.command = a;
      else o.args.push_back(a);
      continue;
    }
    if (a == "--") {
      only_positional = true;
      continue;
    }
    std::optional<std::string> inline_value;
    if (const auto eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos) {
      inline_value = a.substr(eq + 1);
      a = a.substr(0, eq);
    }
    const auto value = [&](const char* what) -> std::string {
      if (inline_value) return *inline_value;
      if (i + 1 >= argc) fail(kExitUsage, a + " needs " + what);
      return argv[++i];
    };
    const auto non_negative = [&](const char* what) -> int64_t {
      const std::string v = value(what);
      const auto n = parse_int(v);
      if (!n || *n < 0) fail(kExitUsage, a + " needs " + what + ", got '" + shown(v) + "'");
      return *n;
    };
    if (a == "-h" || a == "--help") o.help = true;
    else if (a == "--version") o.version = true;
    else if (a == "--json") {
      o.json = true;
      o.given.insert(a);
    } else if (a == "--lcm") o.lcm_url = value("an LCM URL");
    else if (a == "--key-file") {
      o.key_file = value("a key file");
      key_given = true;
    } else if (a == "--host-file") host_file = value("a host file");
    else if (a == "--timeout") {
      o.timeout_ms = non_negative("a number of milliseconds");
      if (o.timeout_ms == 0 || o.timeout_ms > kMaxWaitMs) fail(kExitUsage, "--timeout takes 1..86400000 ms (a day)");
    } else if (a == "--discover-ms") {
      o.discover_ms = non_negative("a number of milliseconds");
      if (o.discover_ms > kMaxWaitMs) fail(kExitUsage, "--discover-ms takes 0..86400000 ms (a day)");
    } else if (a == "--i64") {
      const std::string v = value("a 64-bit integer");
      o.i64 = parse_int(v);
      if (!o.i64) fail(kExitUsage, "--i64 needs a 64-bit integer, got '" + shown(v) + "'");
      o.given.insert(a);
    } else if (a == "--retries") {
      o.retries = non_negative("a number of retries");
      if (o.retries > 10) fail(kExitUsage, "--retries takes 0..10");
    } else if (a == "--window") {
      o.window = non_negative("a number of samples");
      if (o.window < 2 || o.window > 1000000) fail(kExitUsage, "--window takes 2..1000000 samples");
      o.given.insert(a);
    } else if (a == "--time") {
      o.time_ns = non_negative("a host time in ns (0: newest)");
      o.given.insert(a);
    } else if (a == "--count") {
      o.count = non_negative("a number of samples");
      if (o.count == 0) fail(kExitUsage, "--count needs at least 1");
      o.given.insert(a);
    } else if (a == "--period") {
      const std::string v = value("a period in milliseconds");
      const auto p = parse_double(v);
      // At most a day (as a host file's *_ms): 1e308 ms was rounded to nanoseconds
      // out of int64_t's range (an unspecified period sent to the component).
      if (!p || *p < 0 || *p > 86400000.0) {
        fail(kExitUsage, "--period needs milliseconds in 0..86400000 (a day), got '" + shown(v) + "'");
      }
      o.period_ms = *p;
      o.given.insert(a);
    } else if (a == "--duration") {
      const std::string v = value("a number of seconds");
      const auto d = parse_double(v);
      if (!d || *d <= 0 || *d > 60) fail(kExitUsage, "--duration needs seconds in (0, 60], got '" + shown(v) + "'");
      o.duration_s = *d;
      o.given.insert(a);
    } else if (a == "--out") {
      o.out = value("a file");
      o.given.insert(a);
    } else if (a == "--host") {
      o.host = value("a host name");
      o.given.insert(a);
    } else if (a == "--format") {
      o.format = value("dot, svg or json");
      if (o.format != "dot" && o.format != "svg" && o.format != "json") {
        fail(kExitUsage, "--format takes dot, svg or json, got '" + shown(o.format) + "'");
      }
      o.given.insert(a);
    } else if (a == "--live") {
      o.live = true;
      o.given.insert(a);
    } else if (a == "--rackd") {
      o.rackd = value("the rackd program");
      o.given.insert(a);
    } else {
      fail(kExitUsage, "unknown option '" + shown(a) + "' (rackctl --help lists them)");
    }
  }
  if (!host_file.empty()) {
    // The same network and key as the host whose file this is (a GUI does the same
    // with rack::read_tool_network and tims::NetworkConfig::key_file).
    const rack::ToolNetwork net = rack::read_tool_network(host_file);
    if (!net.errors.empty()) fail(kExitUsage, net.errors.front().str());
    if (o.lcm_url.empty()) o.lcm_url = net.url;
    if (!key_given) o.key_file = net.key_file;
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  // A file size limit (ulimit -f) makes write() fail with EFBIG, which is said, and the
  // temporary file removed; SIGXFSZ would have killed rackctl half-way through instead.
  ::signal(SIGXFSZ, SIG_IGN);
  Options o;
  try {
    o = parse_arguments(argc, argv);
  } catch (const Failure& f) {
    print_failure(f.message);
    return f.code;
  }
  if (o.version) {
    rack::print_version("rackctl");
    return kExitOk;
  }
  if (o.command.empty()) {
    if (o.help) {
      std::fputs(kUsage, stdout);
      return kExitOk;
    }
    std::fputs(kUsage, stderr);
    return kExitUsage;
  }
  const Command* cmd = find_command(o.command);
  if (cmd == nullptr) {
    std::fprintf(stderr, "rackctl: unknown command '%s' (rackctl --help lists them)\n", shown(o.command).c_str());
    return kExitUsage;
  }
  if (std::string(cmd->name) == "help") {
    if (o.args.empty()) {
      std::fputs(kUsage, stdout);
      return kExitOk;
    }
    const Command* about = find_command(o.args[0]);
    if (about == nullptr || o.args.size() > 1) {
      std::fprintf(stderr, "rackctl: no command '%s' (rackctl --help lists them)\n", shown(o.args[0]).c_str());
      return kExitUsage;
    }
    print_command_help(*about, stdout);
    return kExitOk;
  }
  if (o.help) {
    print_command_help(*cmd, stdout);
    return kExitOk;
  }
  if (o.args.size() < cmd->min_args || o.args.size() > cmd->max_args) {
    std::fprintf(stderr, "rackctl: %s: wrong number of arguments (%zu)\n\n", cmd->name, o.args.size());
    print_command_help(*cmd, stderr);
    return kExitUsage;
  }
  for (const auto& opt : o.given) {
    if (cmd->options.count(opt) == 0) {
      std::fprintf(stderr, "rackctl: %s does not take %s\n\n", cmd->name, opt.c_str());
      print_command_help(*cmd, stderr);
      return kExitUsage;
    }
  }
  if (std::string(cmd->name) == "doctor") return run_doctor_command(o);
  if (std::string(cmd->name) == "threads") return cmd_threads(o);
  if ((std::string(cmd->name) == "graph" || std::string(cmd->name) == "alloc") && !o.live) {
    try {  // offline: from the host files alone, no network joined
      return std::string(cmd->name) == "graph" ? run_graph(nullptr, o) : run_alloc(nullptr, o);
    } catch (const Failure& f) {
      print_failure(f.message);
      return f.code;
    }
  }
  if (std::string(cmd->name) == "keygen") {
    const std::string err = tims::generate_key_file(o.args[0]);
    if (!err.empty()) {
      std::fprintf(stderr, "rackctl: keygen: %s\n", err.c_str());
      return kExitError;
    }
    std::printf("%s: new key written (mode 0600)\n", o.args[0].c_str());
    return kExitOk;
  }
  try {
    Session session(o);
    return cmd->run(session, o);
  } catch (const Failure& f) {
    print_failure(f.message);
    return f.code;
  } catch (const std::exception& e) {
    // Set-up failures: the LCM network cannot be joined, a mailbox is taken.
    print_failure(e.what());
    return kExitUnavailable;
  }
}
