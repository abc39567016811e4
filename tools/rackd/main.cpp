// rackd: the one executor per host. Reads a host file, validates it, deploys its
// components as SCHED_FIFO tasks, runs until SIGINT/SIGTERM, then switches them OFF
// in reverse dependency order and exits 0.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <cstring>
#include <iostream>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "rack/components/builtin.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/core/payload_json.h"
#include "rack/core/plugin_abi.h"
#include "rack/core/registry.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/pm_qos.h"
#include "rack/rt/modeswitch.h"
#include "rack/rt/thread_birth.h"
#include "rack/tims/lcm_url.h"
#include "rack/version.h"

namespace {

constexpr const char* kUsage = R"(usage: rackd [options] HOSTFILE.yaml

Runs the components listed in a host file (configs/demo.yaml shows every key; an
installed tree has it in <prefix>/share/rack/configs) until SIGINT or SIGTERM, then
switches them OFF in reverse dependency order.

options:
  --check            validate the host file and exit (nothing is started); also
                     checks that the files and folders it names exist
  --duration SEC     shut down by itself after SEC seconds (as on SIGTERM)
  --status SEC       print each component's state and timing every SEC seconds
                     (at least 0.01; default 0: only at shutdown), and each
                     task's page faults since its start-up (0 is the target for
                     an RT task)
  --lcm URL          TiMS/LCM network, instead of the host file's lcm_url (or of
                     the first network under 'tims: networks:')
  --crash-dir DIR    where mode-switch and crash reports go, instead of the host
                     file's modeswitch.crash_dir (default /var/tmp/rack); the report
                     file is DIR/rackd-PID.report (removed at exit when empty);
                     symbolize it with rack-backtrace
  --list-classes [HOSTFILE ...]
                     print the built-in component classes and their parameters, and
                     the plug-in classes (by their manifests, without loading them),
                     then exit; with host files, their plugins: directories are
                     searched too and the plug-in classes they name are loaded and
                     described in full (parameters, component references), as
                     rackctl graph and rack-gui's editor need them
  --json             with --list-classes: one JSON array, each class with its
                     TiMS class id and parameters (kind, unit, min, max, default, doc, choices,
                     required, init_only, component_ref), as rack-gui's editor uses it
                     (a plug-in class not loaded: impl, class, summary, no parameters)
  -h, --help         this text
  --version          the version (CMake project version, git describe)

The log (GDOS: executor events and the components' log calls) goes to stderr, one
line per record, and to LCM for the gdos viewer; the host file's gdos: map sets
levels and outputs (configs/demo.yaml), `rackctl set-param NAME gdosLevel LEVEL`
changes a component's level at run time.

CPU partitioning (the host file's cpus: block, configs/partitioned.yaml): RT
tasks on the 'rt' CPUs, every other thread of rackd (non-RT tasks, GDOS, TiMS/LCM,
library threads) on the 'housekeeping' CPUs; a thread that a library or an RT task
starts is born there with SCHED_OTHER (rackd's pthread_create), one born otherwise
is moved and named. rackd prints where each thread runs at start and warns when an
RT CPU also serves housekeeping (rackctl threads).

Access control (the host file's access: section, configs/access_control.yaml):
which sources may send which messages to which component, at what priority and
rate; refusals are answered ERROR, counted per rule (--status) and logged.
Without the section every source may send everything (rackd warns at start).
Authenticated links: a network under 'tims: networks:' with key_file: PATH signs
and verifies every TiMS packet; the file (rackctl keygen PATH) must be readable
by its owner only, or rackd refuses it (exit 2, with its path and mode). rackd
re-reads a changed key file within a second (key rotation without a restart).

Plug-ins: classes that link large libraries (MCL, ChassisReplay, LadarReplay,
Scan3D, Camera, ObjRecogCamera) are plug-ins, loaded only when a host file names
them: found by class name as CLASS.rack-class in the host file's `plugins:`
directories, then RACK_PLUGIN_PATH (':'-separated), then the build tree's (only
for a rackd of the build tree), then the installed plug-in directory beside this
rackd (../lib/rack/plugins) and the configured prefix's. A missing or broken plug-in is an error naming the
class and the directories searched (also with --check). A plug-in built against
other RACK-RT headers (an older or newer SDK) is refused before any of its code
runs, with the ABI it was built for and the one this rackd expects (--list-classes
prints it): rebuild it against this RACK-RT (README, "Plug-ins and the ABI stamp").

Paths in a host file (plug-ins, key_file, crash_dir, maps, logs, calibration and
output files in parameters) are relative to the host file's folder, not to the
working directory: `rackd configs/sim_mcl.yaml` runs from anywhere. rackd stores
them absolute (rackctl params shows them so) and says so in errors. A relative path
in `rackctl set-param` or STORE_DATA is relative to the host file's folder too.

Host files are read strictly (README "Running a host"): a regular file of at most
1 MiB (FIFOs and devices are refused), UTF-8 without NUL or control characters, one
YAML document, no key twice in a map, at most 32 levels deep and 4096 bytes per
value, integers in range (no wrap-around), times in ms at most a day, valid LCM
URLs, tims expiry_ms at least twice announce_ms, host names 1..63 and component and
network names 1..31 characters, and each class's parameter rules (the same that
`rackctl set-param` and init() apply).

Start-up: SIGINT or SIGTERM while loading or starting ends rackd within a second:
it stops between steps and undoes them, or, if a step does not return (a slow
init()), exits after 500 ms; it says what it was doing. Exit 1 either way.

exit codes: 0 clean shutdown or valid host file, 1 could not start (real-time
required but missing, a task or the network could not start, stopped by a signal
during start-up), 2 usage error or invalid host file (each problem printed as
file:line:col: message).
)";

void list_classes(const rack::ComponentRegistry& registry) {
  std::printf("built-in classes (and plug-in classes a host file given loaded):\n");
  std::printf("plug-ins must be built for plug-in %s (rack/core/plugin_abi.h)\n",
              rack::plugin_abi::describe_stamp(rack::plugin_abi::rackd_stamp()).c_str());
  std::vector<std::string> manifest_problems;
  const auto manifests = registry.plugin_classes(&manifest_problems);
  for (const auto* cls : registry.all()) {
    auto c = cls->make();
    const bool plugin = std::any_of(manifests.begin(), manifests.end(),
                                    [&](const auto& p) { return p.impl == cls->impl; });
    std::printf("%s  (class %s, data task: %s%s)\n  %s\n", cls->impl.c_str(),
                rack::tims::class_name(cls->class_id) ? rack::tims::class_name(cls->class_id) : cls->impl.c_str(),
                rack::describe(c->data_task_mode()), plugin ? ", plug-in, loaded" : "", cls->description.c_str());
    const auto& params = c->parameters();
    for (std::size_t i = 0; i < params.size(); ++i) {
      const auto& p = params.at(i);
      std::printf("    %-14s %-6s %s%s%s\n", p.name().c_str(), rack::describe(p.kind()),
                  p.spec().required ? "(required) " : ("= " + p.value_text() + "  ").c_str(), p.spec().doc.c_str(),
                  p.spec().component_ref ? " [component]" : "");
    }
  }
  // Plug-in classes by their manifests: the libraries (MRPT, PCL, OpenCV) are not
  // loaded for a listing; their parameters: a host file with the class and --check.
  std::vector<std::string> problems;
  const auto plugins = registry.plugin_classes(&problems);
  std::string dirs;
  for (const auto& d : registry.plugin_dirs()) dirs += (dirs.empty() ? "" : ":") + d;
  std::printf("plug-in classes (loaded when a host file names them; searched: %s):\n", dirs.c_str());
  for (const auto& p : plugins) {
    std::printf("%s  (class %s, plug-in %s)\n  %s\n", p.impl.c_str(),
                p.interface_name.empty() ? "?" : p.interface_name.c_str(), p.library.c_str(), p.summary.c_str());
  }
  for (const auto& p : problems) std::printf("rackd: skipped a broken manifest: %s\n", p.c_str());
}

// --list-classes --json: the same as one JSON array, each class as it describes itself
// to tools (rack/core/class_description.h), for programs (rack-gui's host-file editor
// builds its forms from it). Plug-in classes: name, class and summary only.
void list_classes_json(const rack::ComponentRegistry& registry) {
  const auto q = [](const std::string& s) {
    std::string out(1, '"');
    out += rack::json_escape(s);
    out += '"';
    return out;
  };
  const auto number = [](double v) {
    if (!std::isfinite(v)) return std::string("null");  // unbounded
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return std::string(buf);
  };
  std::string out = "[";
  bool first = true;
  std::vector<std::string> problems;
  const auto plugins = registry.plugin_classes(&problems);
  std::set<std::string> loaded_plugins;  // described in full below: not again by their manifests
  for (const auto* cls : registry.all()) {
    auto c = cls->make();
    const rack::ClassDescription d = rack::describe_class(*cls, c->parameters());
    const bool plugin = std::any_of(plugins.begin(), plugins.end(), [&](const auto& p) { return p.impl == d.impl; });
    if (plugin) loaded_plugins.insert(d.impl);
    out += (first ? "" : ",") + std::string("{\"impl\":") + q(d.impl) + ",\"class\":" + q(d.class_name) +
           ",\"summary\":" + q(d.summary) + ",\"data_task\":" + q(rack::describe(c->data_task_mode())) +
           ",\"class_id\":" + std::to_string(cls->class_id) + ",\"plugin\":" + (plugin ? "true" : "false") +
           ",\"parameters\":[";
    first = false;
    for (std::size_t i = 0; i < d.parameters.size(); ++i) {
      const auto& p = d.parameters[i];
      std::string choices;
      for (std::size_t k = 0; k < p.choices.size(); ++k) {
        if (k > 0) choices += ',';
        choices += q(p.choices[k]);
      }
      out += (i == 0 ? "{" : ",{") + std::string("\"name\":") + q(p.name) + ",\"kind\":" + q(rack::describe(p.kind)) +
             ",\"unit\":" + q(p.unit) + ",\"min\":" + number(p.min) + ",\"max\":" + number(p.max) +
             ",\"default\":" + q(p.default_value) + ",\"doc\":" + q(p.doc) + ",\"choices\":[" + choices +
             "],\"required\":" + ((p.flags & rack::ParameterDescription::kRequired) != 0 ? "true" : "false") +
             ",\"init_only\":" + ((p.flags & rack::ParameterDescription::kInitOnly) != 0 ? "true" : "false") +
             ",\"component_ref\":" + ((p.flags & rack::ParameterDescription::kComponentRef) != 0 ? "true" : "false") +
             "}";
    }
    out += "]}";
  }
  for (const auto& p : plugins) {
    if (loaded_plugins.count(p.impl) != 0) continue;
    out += (first ? "" : ",") + std::string("{\"impl\":") + q(p.impl) + ",\"class\":" + q(p.interface_name) +
           ",\"summary\":" + q(p.summary) + ",\"plugin\":true}";
    first = false;
  }
  std::printf("%s]\n", out.c_str());
  for (const auto& p : problems) std::fprintf(stderr, "rackd: skipped a broken manifest: %s\n", p.c_str());
}

// SIGINT/SIGTERM during loading and starting (they are blocked in every thread; the
// main thread waits for them only once the host runs). A watcher thread takes them
// meanwhile: it says what start-up was doing, asks it to stop (the executor checks
// between its steps and undoes what it started), and if start-up has not returned
// within kStopGraceMs (a read or a library call that does not return: a map on a slow
// disk, a device that does not answer) it ends the process itself with exit 1, so
// that rackd always ends within a second of the signal. A second signal ends it at once.
class StartupWatch {
 public:
  static constexpr int64_t kStopGraceMs = 500;

  explicit StartupWatch(const sigset_t& signals) : signals_(signals), thread_([this] { run(); }) {}
  ~StartupWatch() { finish(); }
  StartupWatch(const StartupWatch&) = delete;
  StartupWatch& operator=(const StartupWatch&) = delete;

  // What start-up does now, for the message when a signal comes.
  void phase(const std::string& what) {
    const std::lock_guard lock(mutex_);
    phase_ = what;
  }
  [[nodiscard]] bool stop_requested() const noexcept { return signal_.load(std::memory_order_acquire) != 0; }
  [[nodiscard]] int signal() const noexcept { return signal_.load(std::memory_order_acquire); }
  // Start-up is over (the host runs, or rackd exits): the watcher ends; a signal it
  // took meanwhile stays readable through signal().
  void finish() {
    {
      const std::lock_guard lock(mutex_);
      finished_ = true;
    }
    if (thread_.joinable()) thread_.join();
  }

 private:
  bool finished() {
    const std::lock_guard lock(mutex_);
    return finished_;
  }
  std::string current_phase() {
    const std::lock_guard lock(mutex_);
    return phase_;
  }
  void run() {
    pthread_setname_np(pthread_self(), "rackd:start");
    int sig = 0;
    while (sig <= 0) {
      if (finished()) return;
      timespec ts{0, 20'000'000};
      sig = sigtimedwait(&signals_, nullptr, &ts);
    }
    signal_.store(sig, std::memory_order_release);
    if (finished()) return;  // the host runs: main shuts it down as on any signal
    std::fprintf(stderr, "rackd: %s during start-up (%s): stopping\n", strsignal(sig), current_phase().c_str());
    const int64_t deadline = rack::rt::monotonic_ns() + kStopGraceMs * rack::rt::kNsPerMs;
    while (!finished()) {
      const int64_t left = deadline - rack::rt::monotonic_ns();
      if (left <= 0) break;
      timespec ts = rack::rt::to_timespec(std::min<int64_t>(left, 10 * rack::rt::kNsPerMs));
      if (sigtimedwait(&signals_, nullptr, &ts) > 0) break;  // a second signal: now
    }
    if (finished()) return;
    std::fprintf(stderr, "rackd: start-up did not stop within %lld ms (still %s): exiting now (exit 1)\n",
                 static_cast<long long>(kStopGraceMs), current_phase().c_str());
    std::fflush(stdout);
    _exit(1);
  }

  sigset_t signals_;
  std::mutex mutex_;
  std::string phase_ = "starting";
  bool finished_ = false;
  std::atomic<int> signal_{0};  // release/acquire: the phase text written before is visible with it
  std::thread thread_;
};

// Stops the mode-switch detector (its reporter thread) on every way out of main: a
// thread left running at exit would end in std::terminate and a false crash report.
struct DetectorStop {
  bool active = false;
  ~DetectorStop() {
    if (active) rack::rt::modeswitch::stop();
  }
};

int stopped_during_startup(const StartupWatch& watch) {
  std::fprintf(stderr, "rackd: stopped during start-up by %s; nothing runs (exit 1)\n", strsignal(watch.signal()));
  return 1;
}

}  // namespace

// Publishes each mode-switch report as one GDOS warning line of the component that
// caused it (the report file keeps the whole backtrace). Runs on the detector's
// reporter thread (not RT).
class GdosReportSink final : public rack::rt::modeswitch::ReportSink {
 public:
  explicit GdosReportSink(rack::Executor& executor) : executor_(&executor) {}
  void publish(const rack::rt::modeswitch::ReportView& r, std::string_view) override {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (executor_ == nullptr) return;
    const auto source = rack::tims::parse_address(r.label);
    std::string line = std::string("mode switch ") + rack::rt::modeswitch::reason_name(r.reason) + " #" +
                       std::to_string(r.sequence) + " in task " + std::string(r.task) + ": " + std::string(r.detail) +
                       " (rack-backtrace on the report file gives the line)";
    executor_->publish_report(rack::gdos::Level::kWarning, line, source.value_or(rack::tims::Address()),
                              std::string(r.component));
  }
  void detach() {
    const std::lock_guard<std::mutex> lock(mutex_);
    executor_ = nullptr;
  }

 private:
  std::mutex mutex_;
  rack::Executor* executor_;
};

static int run_rackd(int argc, char** argv) {
  // Block the shutdown signals first, in every thread to come: one that comes during
  // start-up waits for the StartupWatch (below), later for main's loop.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  std::string file, lcm_url, crash_dir;
  std::vector<std::string> more_files;  // --list-classes: every host file after the first
  bool check = false, classes = false, json = false;
  double duration = -1, status_every = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "rackd: %s needs %s (rackd --help lists the options)\n", a.c_str(), what);
        std::exit(2);
      }
      return argv[++i];
    };
    // Seconds: 0, or min_s up to kMaxSeconds. Empty, "nan", "inf" and 1e300 are refused:
    // strtod read "" as 0 (stop at once), NaN passed `d < 0` (never stop), and 1e300 s
    // overflowed the deadline in ns (undefined behaviour; in practice it stopped at once).
    auto number = [&](const char* what, double min_s) {
      constexpr double kMaxSeconds = 1e9;  // 31 years: the deadline in ns stays far from INT64_MAX
      const std::string v = value(what);
      char* end = nullptr;
      const double d = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !(d == 0 || (d >= min_s && d <= kMaxSeconds))) {
        if (min_s > 0) {
          std::fprintf(stderr, "rackd: %s needs %s (0, or %g to %g), got '%s'\n", a.c_str(), what, min_s, kMaxSeconds,
                       v.c_str());
        } else {
          std::fprintf(stderr, "rackd: %s needs %s (0 to %g), got '%s'\n", a.c_str(), what, kMaxSeconds, v.c_str());
        }
        std::exit(2);
      }
      return d;
    };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (a == "--version") {
      rack::print_version("rackd");
      return 0;
    }
    if (a == "--check") check = true;
    else if (a == "--list-classes") classes = true;
    else if (a == "--json") json = true;
    else if (a == "--duration") duration = number("a number of seconds", 0.0);
    // At most 100 reports a second: a period that rounds to 0 ns printed without pause.
    else if (a == "--status") status_every = number("a number of seconds", 0.01);
    else if (a == "--lcm") lcm_url = value("an LCM URL");
    else if (a == "--crash-dir") crash_dir = value("a directory");
    else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "rackd: unknown option '%s' (rackd --help lists the options)\n", a.c_str());
      return 2;
    } else if (file.empty()) file = a;
    else more_files.push_back(a);
  }
  if (!more_files.empty() && !classes) {
    std::fprintf(stderr, "rackd: one host file only ('%s' and '%s')\n", file.c_str(), more_files[0].c_str());
    return 2;
  }
  if (json && !classes) {
    std::fprintf(stderr, "rackd: --json goes with --list-classes\n");
    return 2;
  }
  if (file.empty() && !classes) {
    // What to do, in a few lines: the whole usage would scroll this line away.
    std::fprintf(stderr,
                 "rackd: no host file given: rackd HOSTFILE.yaml [options]\n"
                 "  e.g. rackd configs/demo.yaml --status 1     (every key, commented; installed: in\n"
                 "                                               <prefix>/share/rack/configs)\n"
                 "       rackd --check FILE.yaml                 (validate a host file only)\n"
                 "       rackd --list-classes                    (the component classes)\n"
                 "  rackd --help for every option\n");
    return 2;
  }
  // Before the first thread: service threads get 1 MiB stacks (locked whole by
  // mlockall), not RLIMIT_STACK's 8 MiB.
  rack::rt::limit_default_thread_stack();
  // From here on a signal stops start-up within a second (StartupWatch).
  StartupWatch watch(stop_signals);
  watch.phase("registering the component classes");
  rack::ComponentRegistry registry;
  rack::components::register_builtin(registry);
  if (classes) {
    // The host files' plug-ins: their `plugins:` directories are searched and the
    // plug-in classes they name are loaded, so that these are described in full.
    // A file's errors do not stop the listing (a line each on stderr).
    if (!file.empty()) more_files.insert(more_files.begin(), file);
    const rack::rt::RtCapabilities caps = rack::rt::probe_capabilities();
    for (const auto& f : more_files) {
      const auto loaded = rack::load_host_file(f, registry, caps,
                                               rack::HostLoadOptions{.open_files = true, .check_paths = false});
      if (watch.stop_requested()) return stopped_during_startup(watch);
      for (const auto& e : loaded.errors) {
        std::fprintf(stderr, "rackd: --list-classes: %s (its classes are listed as far as they load)\n",
                     e.str().c_str());
      }
    }
    if (json) list_classes_json(registry);
    else list_classes(registry);
    return 0;
  }

  if (!lcm_url.empty()) {
    if (const auto u = rack::tims::parse_lcm_url(lcm_url); !u.ok()) {
      std::fprintf(stderr, "rackd: --lcm: %s\n", u.error.c_str());
      return 2;
    }
  }

  watch.phase("reading " + file);
  const rack::rt::RtCapabilities caps = rack::rt::probe_capabilities();
  // --check also makes sure that the files the parameters name exist; a start leaves
  // a missing one to its component (that one fails, the others run).
  auto loaded = rack::load_host_file(file, registry, caps,
                                     rack::HostLoadOptions{.open_files = true, .check_paths = check});
  if (watch.stop_requested()) return stopped_during_startup(watch);
  // Warnings (a parameter by its former name): said, then the host starts.
  for (const auto& w : loaded.warnings) std::fprintf(stderr, "%s (warning)\n", w.str().c_str());
  if (!loaded.errors.empty()) {
    // A hostile file can hold thousands: the first kMaxShown say enough.
    constexpr std::size_t kMaxShown = 50;
    for (std::size_t i = 0; i < loaded.errors.size() && i < kMaxShown; ++i) {
      std::fprintf(stderr, "%s\n", loaded.errors[i].str().c_str());
    }
    if (loaded.errors.size() > kMaxShown) {
      std::fprintf(stderr, "%s: ... and %zu more\n", file.c_str(), loaded.errors.size() - kMaxShown);
    }
    std::fprintf(stderr, "rackd: %zu error(s) in %s; nothing started\n", loaded.errors.size(), file.c_str());
    return 2;
  }
  if (check) {
    std::printf("%s: valid (%zu component(s))\n", file.c_str(), loaded.host->components.size());
    return 0;
  }
  DetectorStop detector_stop;
  const rack::HostSettings settings = loaded.host->settings;
  std::fprintf(stderr, "rackd: host '%s' system %u, %zu components from %s\n", settings.host.c_str(), settings.system,
               loaded.host->components.size(), file.c_str());
  std::fprintf(stderr, "rackd: %s\n", caps.describe().c_str());
  if (!settings.housekeeping_cpus.empty()) {
    // Partitioning: from here on every thread this one starts (the mode-switch
    // reporter, the executor's GDOS and network threads, threads of libraries such as
    // OpenMP's pool) inherits the housekeeping CPUs; the tasks get theirs explicitly.
    // Threads started before (the start-up watch, plug-ins') are moved after start().
    const int rc = rack::rt::set_thread_affinity(0, settings.housekeeping_cpus);
    std::fprintf(stderr, "rackd: cpus: RT tasks on CPU %s, housekeeping on CPU %s%s%s\n",
                 rack::rt::cpu_list_string(settings.rt_cpus).c_str(),
                 rack::rt::cpu_list_string(settings.housekeeping_cpus).c_str(),
                 rc == 0 ? "" : "; WARNING: ", rc == 0 ? "" : std::strerror(rc));
  }
  const bool rt_ok = caps.sched_fifo && caps.memlock;
  if (settings.require_rt && (!rt_ok || !caps.preempt_rt)) {
    std::string missing;
    if (!caps.sched_fifo) missing += " SCHED_FIFO rights (CAP_SYS_NICE or an rtprio limit);";
    if (!caps.memlock) missing += " memory locking (CAP_IPC_LOCK or an unlimited memlock limit);";
    if (!caps.preempt_rt) missing += " a PREEMPT_RT kernel;";
    std::fprintf(stderr,
                 "rackd: %s demands real time (require_rt: true) but this host lacks:%s refusing to start. "
                 "`rackctl doctor` prints the fix for each.\n",
                 file.c_str(), missing.c_str());
    return 1;
  }
  if (!rt_ok) {
    std::string why;
    if (!caps.sched_fifo) why += "SCHED_FIFO refused";
    if (!caps.memlock) why += std::string(why.empty() ? "" : ", ") + "memory cannot be locked";
    std::fprintf(stderr,
                 "rackd: WARNING: no real-time rights (%s): tasks run with normal scheduling and timing is not "
                 "guaranteed. Run as root, grant CAP_SYS_NICE and CAP_IPC_LOCK, or give this user 'rtprio 99' and "
                 "'memlock unlimited' in /etc/security/limits.conf (log in again); `rackctl doctor` checks this "
                 "machine and prints each fix (README \"Real-time set-up on a robot\").\n",
                 why.c_str());
  }
  if (!caps.preempt_rt) {
    std::fprintf(stderr, "rackd: note: the kernel is not PREEMPT_RT; latencies are those of a stock kernel.\n");
  }
  watch.phase("locking memory and pre-faulting " + std::to_string(settings.heap_prefault_bytes >> 20) + " MiB of heap");
  const auto mem = rack::rt::apply_memory_policy(settings.heap_prefault_bytes);
  if (watch.stop_requested()) return stopped_during_startup(watch);
  std::fprintf(stderr, "rackd: %s\n", mem.describe().c_str());
  if (const auto libs = registry.unlockable_libraries(); !libs.empty() && mem.locked) {
    // A plug-in whose libraries only non-RT work runs (MCL's MRPT): not locked.
    const std::size_t bytes = rack::rt::unlock_file_mappings(libs);
    std::fprintf(stderr, "rackd: %zu MiB of %zu plug-in libraries left unlocked (used by non-RT tasks only)\n",
                 bytes >> 20, libs.size());
  }
  if (settings.require_rt && !mem.locked) {
    std::fprintf(stderr, "rackd: require_rt is set and memory could not be locked: refusing to start.\n");
    return 1;
  }
  const rack::rt::CpuLatencyHold cpu_latency(settings.cpu_dma_latency_us);
  std::fprintf(stderr, "rackd: %s\n", cpu_latency.describe().c_str());

  // Mode-switch detection and crash reports: after the memory policy (so NOMLOCK
  // reflects it) and the plug-ins (so their load addresses are recorded), before
  // any task starts.
  rack::rt::modeswitch::Config detection = settings.modeswitch;
  detection.program = "rackd";
  if (!crash_dir.empty()) detection.crash_dir = crash_dir;
  watch.phase("starting mode-switch detection");
  const auto detector = rack::rt::modeswitch::start(detection);
  detector_stop.active = true;
  std::fprintf(stderr, "rackd: %s\n", detector.describe().c_str());

  rack::ExecutorOptions options;
  options.allow_rt_fallback = !settings.require_rt;
  options.lcm_url_override = lcm_url;
  options.stop_requested = [&watch] { return watch.stop_requested(); };
  options.phase = [&watch](const std::string& what) { watch.phase(what); };
  rack::Executor executor(std::move(loaded.host), options);
  try {
    executor.start();
  } catch (const rack::StartStopped&) {
    return stopped_during_startup(watch);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rackd: cannot start: %s\n", e.what());
    return 1;
  }
  watch.finish();
  // Mode-switch reports also go to GDOS, as a warning of the component that caused
  // them (Xenomai printed SIGDEBUG reports on the console; a robot's operator reads
  // GDOS). The reporter thread calls the sink; it is detached before the executor stops.
  const auto gdos_sink = std::make_shared<GdosReportSink>(executor);
  rack::rt::modeswitch::add_sink(gdos_sink);
  if (executor.any_fallback() && caps.sched_fifo) {  // the probe said yes, a task was refused
    std::fprintf(stderr, "rackd: WARNING: SCHED_FIFO was refused; tasks run SCHED_OTHER.\n");
  }
  for (const auto& w : executor.partition_warnings()) std::fprintf(stderr, "rackd: WARNING: %s\n", w.c_str());
  (void)executor.partition_threads();  // threads started before the main thread's affinity was set
  if (!settings.housekeeping_cpus.empty()) {
    std::fprintf(stderr, "rackd: cpus: %s\n", rack::rt::thread_birth::describe().c_str());
  }
  std::fprintf(stderr, "rackd: %s", executor.thread_report().c_str());
  std::fprintf(stderr, "rackd: running%s%s; SIGINT or SIGTERM stops\n", executor.transport() ? ", TiMS on " : "",
               executor.transport() ? executor.transport()->url().c_str() : "");

  const int64_t start = rack::rt::monotonic_ns();
  int64_t next_status = status_every > 0 ? start + static_cast<int64_t>(status_every * 1e9) : INT64_MAX;
  const int64_t end = duration >= 0 ? start + static_cast<int64_t>(duration * 1e9) : INT64_MAX;
  int signal_number = watch.signal();  // one that came as start-up ended
  while (signal_number == 0) {
    const int64_t now = rack::rt::monotonic_ns();
    if (now >= end) break;
    if (now >= next_status) {
      std::fprintf(stdout, "[%.1f s]\n%s", static_cast<double>(now - start) * 1e-9, executor.status_report().c_str());
      if (const auto c = rack::rt::modeswitch::counters(); c.reports > 0) {
        std::fprintf(stdout, "  mode switches: %llu reported, %llu dropped; see %s\n",
                     static_cast<unsigned long long>(c.reports), static_cast<unsigned long long>(c.dropped),
                     detector.report_path.empty() ? "stderr" : detector.report_path.c_str());
      }
      std::fflush(stdout);
      next_status += static_cast<int64_t>(status_every * 1e9);
    }
    // Threads that libraries start late (a pool on first use, maybe from an RT task)
    // are born on the housekeeping CPUs (rack/rt/thread_birth.h). The backstop for any
    // born otherwise: a sweep of /proc/self/task when the thread count changed.
    for (const auto& t : executor.partition_new_threads()) {
      std::fprintf(stderr, "rackd: cpus: thread %s (it was not born there)\n", t.c_str());
    }
    const int64_t wait = std::min({end, next_status, now + 100 * rack::rt::kNsPerMs}) - now;
    timespec ts = rack::rt::to_timespec(wait > 0 ? wait : 0);
    const int sig = sigtimedwait(&stop_signals, nullptr, &ts);
    if (sig > 0) signal_number = sig;
  }
  std::fprintf(stderr, "rackd: %s: switching components off\n",
               signal_number != 0 ? strsignal(signal_number) : "duration elapsed");
  std::fprintf(stdout, "final status:\n%s", executor.status_report().c_str());
  std::fflush(stdout);
  gdos_sink->detach();
  executor.stop();
  const auto counts = rack::rt::modeswitch::counters();
  rack::rt::modeswitch::stop();
  if (counts.reports > 0) {
    std::string by;
    for (int k = 1; k < rack::rt::modeswitch::kReasonCount; ++k) {
      if (counts.by_reason[k] == 0) continue;
      by += std::string(by.empty() ? "" : ", ") +
            rack::rt::modeswitch::reason_name(static_cast<rack::rt::modeswitch::Reason>(k)) + " " +
            std::to_string(counts.by_reason[k]);
    }
    std::fprintf(stderr, "rackd: %llu mode switch(es) reported (%s)%s; see %s\n",
                 static_cast<unsigned long long>(counts.reports), by.c_str(),
                 counts.dropped > 0 ? (", " + std::to_string(counts.dropped) + " dropped (ring full)").c_str() : "",
                 detector.report_path.empty() ? "stderr" : detector.report_path.c_str());
  }
  std::fprintf(stderr, "rackd: stopped cleanly\n");
  return 0;
}

int main(int argc, char** argv) {
  // Whatever escapes (an allocation that fails while loading, a library that throws)
  // is a start-up that failed: said as such, exit 1, never std::terminate's abort
  // (which the crash handler would report as a crash).
  try {
    return run_rackd(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rackd: cannot start: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "rackd: cannot start: unknown exception\n");
  }
  return 1;
}
