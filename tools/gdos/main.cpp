// gdos: the live log of every rackd on an LCM network (RACK's GDOS viewer), or the
// replay of a recorded log. Names instead of addresses, colours by level on a
// terminal, filters, --record/--replay, --json for scripts.
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "gdos_view.h"
#include "rack/client/session.h"
#include "rack/rt/clock.h"
#include "rack/client/host_file.h"
#include "rack/tims/gdos_lcm.h"
#include "rack/tims/lcm_transport.h"
#include "rack/version.h"

namespace {

constexpr const char* kUsage = R"(usage: gdos [options]

Shows the GDOS log of every rackd on an LCM network as it happens: one line per
record with time (UTC), host, level (P print, E error, W warning, I info,
D detail), component name and text. Start it before or after the hosts; it
listens until Ctrl-C (or --count / --duration).

options:
  --lcm URL          the LCM network (default: $LCM_DEFAULT_URL, else
                     udpm://239.255.76.67:7667?ttl=0, rackd's default)
  --channel NAME     the GDOS channel (default RACK_GDOS; a host file's
                     gdos.channel)
  --level LEVEL      show records at or below LEVEL: print, error, warning,
                     info, detail (default detail: all); print always shows
  --host HOST        only records from HOST (repeatable)
  --component NAME   only records of component NAME: its host-file name or its
                     address such as Generator(0/1) or, for a plug-in class,
                     Counter(2/0) (repeatable)
  --grep TEXT        only records whose text contains TEXT
  --record FILE      also write every record received (before the filters) to
                     FILE, in gdos's record format (see tools/gdos/README.md)
  --replay FILE      show the records of FILE instead of listening (filters
                     and --json apply); a malformed or truncated file is
                     rejected with the byte offset of the problem (exit 1)
  --json             one JSON object per line (host, pid, time_ns, time,
                     sequence, level, source, source_raw, name, dropped_before,
                     text) instead of text
  --color, --no-color  force colours on or off (default: on when stdout is a
                     terminal and NO_COLOR is unset)
  --count N          exit after N records shown
  --duration SEC     exit after SEC seconds
  --silent           do not announce this viewer (hosts with gdos.stderr: auto
                     keep writing their log to stderr)
  --host-file FILE   the network and key file of this host file (the first of
                     its 'tims: networks:', else its lcm_url); --lcm and
                     --key-file override either (a replay asks that network
                     for class names)
  --key-file FILE    the network's key file (authenticated links; default
                     $RACK_KEY_FILE): records and announcements that do not
                     verify are dropped and counted; without it, signed records
                     are shown unverified
  -h, --help         this text
  --version          the version (CMake project version, git describe)

Addresses name each class as it describes itself to tools: gdos asks the host of
a record's source once per class (GET_CLASS), so a plug-in class built outside
the tree shows as Counter(2/0) like a built-in one. A replay asks the network
too; when the recording's hosts do not answer discovery within 300 ms, its
addresses keep class numbers (Class0x91(2/0)).

Losses are reported on stderr: records a host's ring dropped (its next record
says how many) and records lost on the network (gaps in a host's sequence).
What the network sends that is not a GDOS batch or announcement (not LCM, LCM
fragments, batches that do not decode) is dropped, counted and warned about at
most once a second per kind; the counts are printed at exit. Control
characters in records are shown escaped (\x1b), never sent to the terminal.

exit codes: 0 ok (Ctrl-C, --count or --duration reached, end of a replay),
1 cannot join the network or read/write a file (malformed file included),
2 usage error.
)";

std::atomic<bool> g_stop{false};

// The names of the classes of the records' sources, as each class describes itself
// to tools (GET_CLASS through rack/client/session.h), so that a plug-in's records show
// as Counter(2/0) and `--component Counter(2/0)` selects them: gdos is built with no
// class. Cached per system and class id. A source's host is asked only when it
// answers discovery (waited for once per system, up to 300 ms): a replay without
// its hosts shows TiMS' spelling (Class0x91(2/0)) without waiting on each class.
class ClassNames {
 public:
  ClassNames(std::string url, std::string key_file) : url_(std::move(url)), key_file_(std::move(key_file)) {}

  // "" when TiMS names the class itself (Executor, Tool) or nothing answers.
  const std::string& of(uint32_t source) {
    static const std::string kNone;
    const rack::tims::Address a(source);
    if (rack::tims::class_name(a.class_id()) != nullptr) return kNone;
    const uint32_t key = source & 0xFFFF0000u;
    if (const auto it = names_.find(key); it != names_.end()) return it->second;
    if (!session_ && !open()) return kNone;
    if (!host_heard(a.system())) return kNone;  // asked again with a later record
    const rack::ClassDescription* d = session_->describe(a);
    return names_[key] = d != nullptr ? d->class_name : std::string();
  }

 private:
  bool open() {
    if (failed_) return false;
    rack::client::SessionConfig c;
    c.tool = "gdos";
    c.lcm_url = url_;
    c.key_file = key_file_;
    c.timeout_ms = 300;
    c.retries = 1;
    c.discover_ms = 300;
    c.reply_slot_bytes = 64 * 1024;  // CLASS pages are 8 KiB
    c.streams = false;
    try {
      session_ = std::make_unique<rack::client::Session>(c);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "gdos: class names are not learnt (addresses keep class numbers): %s\n", e.what());
      failed_ = true;
    }
    return !failed_;
  }
  bool host_heard(uint8_t system) {
    const auto heard = [system](const std::vector<rack::tims::HostInfo>& hosts) {
      for (const auto& h : hosts) {
        if (h.system == system && h.role == rack::tims::NodeRole::kExecutor) return true;
      }
      return false;
    };
    if (heard(session_->hosts())) return true;
    if (!waited_.insert(system).second) return false;
    return heard(session_->discover(heard));
  }

  std::string url_, key_file_;
  std::unique_ptr<rack::client::Session> session_;
  bool failed_ = false;
  std::map<uint32_t, std::string> names_;  // system | class id << 16
  std::set<uint8_t> waited_;               // systems discovery was waited for
};
void on_signal(int) { g_stop.store(true); }

[[noreturn]] void usage_error(const std::string& what) {
  std::fprintf(stderr, "gdos: %s\n(gdos --help for the options)\n", what.c_str());
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace rack;
  gdos_view::Filter filter;
  std::string url = rack::client::default_lcm_url();
  std::string channel = tims::kGdosChannel;
  std::string record_path, replay_path;
  std::string key_file = std::getenv("RACK_KEY_FILE") != nullptr ? std::getenv("RACK_KEY_FILE") : "";
  std::string host_file;
  bool key_given = false, url_given = false;
  bool json = false, silent = false;
  std::optional<bool> colour_opt;
  long long count = -1;
  double duration = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> std::string {
      if (i + 1 >= argc) usage_error(a + " needs " + what);
      return argv[++i];
    };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--version") {
      rack::print_version("gdos");
      return 0;
    } else if (a == "--lcm") {
      url = value("an LCM URL");
      url_given = true;
    } else if (a == "--channel") {
      channel = value("a channel name");
      if (channel.empty()) usage_error("--channel needs a non-empty name");
    } else if (a == "--level") {
      const std::string v = value("a level");
      const auto l = gdos::parse_level(v);
      if (!l) usage_error("--level must be one of " + std::string(gdos::kLevelNames) + ", got '" + v + "'");
      filter.max_level = *l;
    } else if (a == "--host") {
      filter.hosts.push_back(value("a host name"));
    } else if (a == "--component") {
      filter.components.push_back(value("a component name or address"));
    } else if (a == "--grep") {
      filter.text = value("a text");
    } else if (a == "--record") {
      record_path = value("a file");
    } else if (a == "--replay") {
      replay_path = value("a file");
    } else if (a == "--json") {
      json = true;
    } else if (a == "--color" || a == "--colour") {
      colour_opt = true;
    } else if (a == "--no-color" || a == "--no-colour") {
      colour_opt = false;
    } else if (a == "--key-file") {
      key_file = value("a key file");
      key_given = true;
    } else if (a == "--host-file") {
      host_file = value("a host file");
    } else if (a == "--silent") {
      silent = true;
    } else if (a == "--count") {
      const std::string v = value("a number");
      char* end = nullptr;
      errno = 0;
      count = std::strtoll(v.c_str(), &end, 10);
      if (v.empty() || *end != '\0' || errno == ERANGE || count <= 0)
        usage_error("--count needs a positive number (at most " + std::to_string(LLONG_MAX) + "), got '" + v + "'");
    } else if (a == "--duration") {
      const std::string v = value("seconds");
      char* end = nullptr;
      duration = std::strtod(v.c_str(), &end);
      // At most 1e9 s (31 years): "inf" or 1e300 s overflowed the deadline in ns
      // (undefined behaviour; in practice gdos stopped at once, saying nothing).
      if (v.empty() || *end != '\0' || !(duration > 0 && duration <= 1e9))
        usage_error("--duration needs seconds in (0, 1e9], got '" + v + "'");
    } else {
      usage_error("unknown argument '" + a + "'");
    }
  }
  if (!record_path.empty() && !replay_path.empty()) usage_error("--record and --replay exclude each other");
  const bool colour = colour_opt.value_or(isatty(STDOUT_FILENO) == 1 && std::getenv("NO_COLOR") == nullptr);

  if (!host_file.empty()) {
    const rack::ToolNetwork net = rack::read_tool_network(host_file);
    if (!net.errors.empty()) usage_error(net.errors.front().str());
    if (!url_given) url = net.url;
    if (!key_given) key_file = net.key_file;
  }
  ClassNames classes(url, key_file);

  long long shown = 0;
  auto show = [&](const tims::GdosRecord& r, const std::string& name) {
    const std::string& cls = classes.of(r.source);
    if (!filter.matches(r, name, cls)) return;
    const std::string line = json ? gdos_view::json_line(r, name, cls) : gdos_view::text_line(r, name, colour, cls);
    std::fputs(line.c_str(), stdout);
    std::fputc('\n', stdout);
    ++shown;
  };

  if (!replay_path.empty()) {
    try {
      gdos_view::RecordReader reader(replay_path);
      tims::GdosRecord r;
      while ((count < 0 || shown < count) && reader.next(r)) show(r, r.name);
    } catch (const std::exception& e) {
      std::fflush(stdout);
      std::fprintf(stderr, "gdos: %s\n", e.what());
      return 1;
    }
    std::fflush(stdout);
    return 0;
  }

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  std::unique_ptr<tims::GdosSubscriber> sub;
  std::unique_ptr<gdos_view::RecordWriter> writer;
  try {
    sub = std::make_unique<tims::GdosSubscriber>(url, channel, !silent, "gdos", key_file);
    if (!record_path.empty()) writer = std::make_unique<gdos_view::RecordWriter>(record_path, url + " " + channel);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gdos: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "gdos: listening on %s channel %s%s\n", url.c_str(), channel.c_str(),
               writer ? (", recording to " + record_path).c_str() : "");
  const int64_t end = duration > 0 ? rack::rt::monotonic_ns() + static_cast<int64_t>(duration * 1e9) : INT64_MAX;
  int exit_code = 0;
  while (!g_stop.load() && (count < 0 || shown < count) && rack::rt::monotonic_ns() < end) {
    try {
      sub->poll(100, [&](const tims::GdosRecord& r) {
        if (writer) writer->write(r);
        if (count >= 0 && shown >= count) return;
        std::string name = r.name;
        if (name.empty()) name = sub->announced_name(r.source);
        show(r, name);
      });
    } catch (const std::exception& e) {
      std::fprintf(stderr, "gdos: %s\n", e.what());
      exit_code = 1;
      break;
    }
    std::fflush(stdout);
    if (writer) writer->flush();
    const std::string w = sub->take_warnings();
    if (!w.empty()) std::fputs(w.c_str(), stderr);
  }
  std::fflush(stdout);
  const auto c = sub->counters();
  std::fprintf(stderr,
               "gdos: %llu record(s) received, %lld shown, %llu lost on the network, %llu malformed batch(es), "
               "refused: %llu announcement(s) that did not decode, %llu datagram(s) not LCM, %llu LCM fragment(s)%s\n",
               static_cast<unsigned long long>(c.records), shown, static_cast<unsigned long long>(c.lost),
               static_cast<unsigned long long>(c.malformed), static_cast<unsigned long long>(c.bad_announcements),
               static_cast<unsigned long long>(c.bad_datagrams), static_cast<unsigned long long>(c.lcm_fragments),
               key_file.empty() ? ""
                                : (", " + std::to_string(c.auth_failed) + " failed authentication, " +
                                   std::to_string(c.replayed) + " replayed")
                                      .c_str());
  if (writer) {
    writer->flush();
    std::fprintf(stderr, "gdos: %llu record(s) written to %s\n", static_cast<unsigned long long>(writer->records()),
                 record_path.c_str());
  }
  return exit_code;
}
