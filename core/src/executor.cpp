#include "rack/core/executor.h"

#include <functional>

#include <algorithm>

#include "rack/core/stepper.h"
#include "rack/rt/thread_birth.h"
#include "rack/tims/lcm_url.h"

#include <dirent.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <cstring>
#include <iostream>
#include <stdexcept>
#include <thread>

namespace rack {

using tims::Address;
namespace msg = tims::msg;

namespace {

// The host's (first) TiMS network: --lcm, else the first of `tims: networks:`, else lcm_url.
std::string first_network_url(const HostSettings& hs, const std::string& lcm_url_override) {
  return !lcm_url_override.empty() ? lcm_url_override : !hs.networks.empty() ? hs.networks.front().url : hs.lcm_url;
}

// The networks GET_TASKS names (wire::TasksReply network_*): the ones the transport
// joins (join_network: --lcm replaces the first one's URL; none listed: one robot
// network on `url`), none when the host does not use LCM.
void fill_host_networks(wire::TasksReply& out, const HostSettings& hs, const std::string& url) {
  if (!hs.lcm || (url.empty() && hs.networks.empty())) return;
  std::vector<tims::NetworkConfig> nets = hs.networks;
  if (nets.empty()) {
    tims::NetworkConfig n;
    n.url = url;
    nets.push_back(n);
  } else if (!url.empty()) {
    nets.front().url = url;
  }
  for (const auto& n : nets) {
    if (out.network_count >= wire::kMaxTaskNetworks) break;
    const std::size_t j = out.network_count++;
    const auto copy = [](char* dst, std::size_t len, const std::string& text) {
      std::size_t i = 0;
      for (; i + 1 < len && i < text.size(); ++i) {
        const auto c = static_cast<unsigned char>(text[i]);
        dst[i] = c >= 0x20 && c <= 0x7e ? text[i] : '?';
      }
      dst[i] = '\0';
    };
    copy(out.network_name + j * wire::kTaskNetworkNameLen, wire::kTaskNetworkNameLen, n.name.empty() ? "?" : n.name);
    copy(out.network_url + j * wire::kTaskNetworkUrlLen, wire::kTaskNetworkUrlLen, n.url);
    out.network_scope[j] = n.scope == tims::NetworkScope::kFleet ? 1 : 0;
  }
}

// Keeps the executor's own non-RT threads (the GDOS thread, the TiMS/LCM transport's
// threads) off the CPUs that the host file pins RT tasks to. On a kernel that is not
// PREEMPT_RT a normal thread inside a system call (a /proc read, a socket send, a log
// write) delays the wake-up of an RT task on its CPU until it reaches a preemption
// point; a pinned control task should share its CPU with nothing of rackd's own that
// it does not need. Threads inherit their creator's affinity, so the creating (main)
// thread holds the reduced set while it starts them and gets its own back after.
// Nothing changes when no RT task is pinned or the pinned tasks take every CPU
// rackd may use. Tasks themselves are created outside this scope (unpinned RT tasks
// keep every CPU).
class HousekeepingAffinity {
 public:
  HousekeepingAffinity(const std::vector<ComponentView>& views, const HostSettings& hs) noexcept {
    CPU_ZERO(&saved_);
    if (pthread_getaffinity_np(pthread_self(), sizeof saved_, &saved_) != 0) return;
    if (!hs.housekeeping_cpus.empty()) {  // partitioned (`cpus:`): exactly the housekeeping CPUs
      cpu_set_t hk;
      CPU_ZERO(&hk);
      for (const int c : hs.housekeeping_cpus) {
        if (c >= 0 && c < CPU_SETSIZE) CPU_SET(static_cast<std::size_t>(c), &hk);
      }
      active_ = CPU_COUNT(&hk) > 0 && pthread_setaffinity_np(pthread_self(), sizeof hk, &hk) == 0;
      return;
    }
    cpu_set_t set = saved_;
    bool removed = false;
    const auto drop = [&](const TaskSettings& t) {
      if (t.priority > 0 && t.cpu >= 0 && t.cpu < CPU_SETSIZE && CPU_ISSET(static_cast<std::size_t>(t.cpu), &set)) {
        CPU_CLR(static_cast<std::size_t>(t.cpu), &set);
        removed = true;
      }
    };
    for (const auto& v : views) {
      const ComponentSettings& s = v.component->settings();
      drop(s.command_task);
      if (v.component->data_task_mode() != DataTaskMode::kNone) drop(s.data_task);
    }
    if (!removed || CPU_COUNT(&set) == 0) return;
    active_ = pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
  }
  ~HousekeepingAffinity() {
    if (active_) (void)pthread_setaffinity_np(pthread_self(), sizeof saved_, &saved_);
  }
  HousekeepingAffinity(const HousekeepingAffinity&) = delete;
  HousekeepingAffinity& operator=(const HousekeepingAffinity&) = delete;
  [[nodiscard]] bool active() const noexcept { return active_; }

 private:
  cpu_set_t saved_;
  bool active_ = false;
};

}  // namespace

Executor::Executor(std::unique_ptr<LoadedHost> host, ExecutorOptions options)
    : host_(std::move(host)), options_(std::move(options)), router_(host_->settings.system) {
  for (auto& c : host_->components) views_.push_back(ComponentView{c.get(), false, {}, false, false, false});
}

Executor::~Executor() { stop(); }

void Executor::log(gdos::Level level, const std::string& line) {
  if (options_.log) options_.log(line);
  hub_.publish_text(level, log_source_.address(), log_source_.name(), line);
}

void Executor::publish_report(gdos::Level level, const std::string& text, Address source,
                              const std::string& source_name) {
  if (source == Address()) hub_.publish_text(level, log_source_.address(), log_source_.name(), text);
  else hub_.publish_text(level, source, source_name, text);
}

void Executor::flush_log() { gdos_pass(); }

void Executor::gdos_pass() {
  std::lock_guard lock(gdos_mutex_);
  const GdosSettings& g = host_->settings.gdos;
  bool to_stderr = g.to_stderr == GdosSettings::Stderr::kAlways;
  if (g.to_stderr == GdosSettings::Stderr::kAuto) {
    // A viewer says it listens once a second; 3 s without one: back to stderr.
    to_stderr = gdos_publisher_ == nullptr || !gdos_publisher_->listener_present(3 * rt::kNsPerSec);
  }
  // Reused, and written out whenever it holds kStderrChunk bytes: however many records
  // a late pass drains (a loaded machine, a burst of info lines), it keeps the capacity
  // reserved by the first pass and the GDOS thread does not allocate for stderr.
  static constexpr std::size_t kStderrChunk = 64 * 1024;
  std::string& out = gdos_out_;
  if (out.capacity() < 2 * kStderrChunk) out.reserve(2 * kStderrChunk);
  out.clear();
  // Access denials: one line per rule with new denials, at most every access.log_ms
  // (the check itself, in RT tasks and receive threads, only counts).
  if (access_ && access_->denied_total() > 0 && rt::monotonic_ns() >= next_access_report_ns_) {
    next_access_report_ns_ = rt::monotonic_ns() + host_->settings.access_log_ns;
    for (const auto& line : access_->report()) {
      hub_.publish_text(gdos::Level::kWarning, log_source_.address(), log_source_.name(), line);
    }
  }
  if (g.to_stderr == GdosSettings::Stderr::kAuto && to_stderr != gdos_to_stderr_) {
    // Say why the log appears on or vanishes from stderr.
    out += to_stderr ? "rackd: GDOS: no gdos viewer listens: the log goes to stderr too\n"
                     : "rackd: GDOS: a gdos viewer listens: the log goes to LCM only (gdos.stderr: auto)\n";
    gdos_to_stderr_ = to_stderr;
  }
  struct Pass {
    bool to_stderr;
    std::string& out;
    tims::GdosPublisher* publisher;
    const std::function<void(const gdos::Record&)>& sink;
  } pass{to_stderr, out, gdos_publisher_.get(), options_.gdos_sink};
  // One captured pointer: fits std::function's small buffer, so an idle pass
  // allocates nothing (the no-allocation tests count every thread).
  hub_.drain([p = &pass](const gdos::Record& r) {
    if (p->to_stderr) {
      gdos::append_line(r, p->out);
      if (p->out.size() >= kStderrChunk) {
        std::fwrite(p->out.data(), 1, p->out.size(), stderr);
        p->out.clear();
      }
    }
    if (p->sink) p->sink(r);
    if (p->publisher != nullptr) {
      p->publisher->add(r.source.raw(), r.name, static_cast<uint8_t>(r.level), r.time_ns, r.sequence, r.dropped_before,
                        r.text);
    }
  });
  if (gdos_publisher_) {
    gdos_publisher_->flush();
    const uint64_t errors = gdos_publisher_->counters().publish_errors;
    if (errors > gdos_errors_reported_) {
      out += "rackd: GDOS: " + std::to_string(errors - gdos_errors_reported_) +
             " batch(es) could not be published on " + gdos_publisher_->url() + "\n";
      gdos_errors_reported_ = errors;
    }
  }
  if (!out.empty()) {
    std::fwrite(out.data(), 1, out.size(), stderr);
    std::fflush(stderr);
  }
}

void Executor::gdos_loop() {
  pthread_setname_np(pthread_self(), "rackd:gdos");  // for top and ps (not RT: SCHED_OTHER)
  const auto period = std::chrono::nanoseconds(host_->settings.gdos.drain_ns);
  int64_t next_fault_sample = 0;
  for (;;) {
    {
      std::unique_lock lock(gdos_mutex_);
      gdos_cv_.wait_for(lock, period, [this] { return !gdos_running_; });
      if (!gdos_running_) break;
    }
    pass_guarded();
    // The RT tasks' page faults since start-up, for GET_STATS (rackctl status): read
    // from /proc here, by a non-RT thread, so that the tasks make no system call for it.
    if (const int64_t now = rt::monotonic_ns(); now >= next_fault_sample) {
      for (const auto& v : views_) {
        v.component->sample_faults();
        v.component->sample_tasks();  // how the tasks run (GET_TASKS): policy, priority, CPUs, period
      }
      next_fault_sample = now + rt::kNsPerSec;
    }
  }
  pass_guarded();  // what the last moments left behind
}

void Executor::pass_guarded() noexcept {
  // The GDOS thread must outlive a failing pass (out of memory while formatting, a
  // sink that throws): say so and go on with the next one.
  try {
    gdos_pass();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rackd: GDOS: a log pass failed: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "rackd: GDOS: a log pass failed\n");
  }
}

Component* Executor::find(const std::string& name_or_address) noexcept {
  const auto parsed = tims::parse_address(name_or_address);
  for (auto& v : views_) {
    if (v.component->name() == name_or_address) return v.component;
    if (parsed && v.component->address() == parsed->component()) return v.component;
  }
  return nullptr;
}

bool Executor::send_command(Component& c, int8_t type, int64_t timeout_ns, std::string& why) {
  alignas(8) std::byte buf[512];
  const auto r = endpoint_->call(c.address(), type, std::span<std::byte>(buf), timeout_ns);
  if (r.status != tims::CallStatus::kOk) {
    why = tims::describe(r.status);
    return false;
  }
  if (r.reply.type != msg::kOk) {
    why = msg::name(r.reply.type) != nullptr ? msg::name(r.reply.type) : "unexpected reply";
    if (r.reply.type == msg::kError && !r.body.empty()) {
      const auto* text = reinterpret_cast<const char*>(r.body.data());
      why += std::string(": ") + std::string(text, strnlen(text, r.body.size()));
    }
    return false;
  }
  return true;
}

void Executor::step(const std::string& what) {
  if (options_.stop_requested && options_.stop_requested()) throw StartStopped();
  if (options_.phase) options_.phase(what);
}

void Executor::start() {
  if (started_) return;
  const HostSettings& hs = host_->settings;
  // Stepped: the stepping thread alone runs the components (rack/core/stepper.h). LCM's
  // threads would deliver messages and run command passes beside it, and a host on the
  // default bus hears every other process on it. PlaybackTest's pipeline host had LCM on
  // (its transport's threads moved the virtual clock: the CI failure of 38aa000).
  if (options_.stepped && hs.lcm) {
    throw std::logic_error(
        "a stepped executor (ExecutorOptions::stepped) runs without LCM: its host file needs 'lcm: false'");
  }
  const std::string url = first_network_url(hs, options_.lcm_url_override);
  // Checked before anything opens them (the host file loader checked its own; this
  // catches --lcm and hosts built in code): LCM itself only prints "invalid URL".
  if (hs.lcm) {
    if (const auto u = tims::parse_lcm_url(url); !url.empty() && !u.ok()) {
      throw std::runtime_error("the TiMS network: " + u.error);
    }
    if (const auto u = tims::parse_lcm_url(hs.gdos.lcm_url); hs.gdos.lcm && !hs.gdos.lcm_url.empty() && !u.ok()) {
      throw std::runtime_error("gdos.lcm_url: " + u.error);
    }
  }
  started_ = true;
  try {
    start_steps(url);
  } catch (...) {
    stop();
    throw;
  }
}

void Executor::start_steps(const std::string& url) {
  const Address self = Address::make(host_->settings.system, tims::classes::kExecutor, host_->settings.host_id, 1);
  // Partitioning: from here on every thread that is not one of our tasks or workers
  // (rt::Thread) is born on the housekeeping CPUs with SCHED_OTHER, whoever creates it
  // (where the program links rack::rt_hooks, as rackd does).
  if (!host_->settings.housekeeping_cpus.empty()) {
    placing_threads_ = rt::thread_birth::place_on(host_->settings.housekeeping_cpus) == 0;
  }
  open_mailboxes(self);
  start_gdos(url, self);  // first, so that everything from here on is logged
  install_access(self);
  attach_components();
  init_components();
  start_io_workers();
  start_compute_workers();
  step("starting the tasks");
  for (auto& v : views_) start_tasks(v);
  join_network(url, self);
  start_trace_thread();
  log_started();
  autostart_components();
  // The start-up events are out before start() returns (rackd then says "running").
  gdos_pass();
}

// The executor's own mailboxes: #1 for commands from main(), #2 for traces.
void Executor::open_mailboxes(Address self) {
  const HostSettings& hs = host_->settings;
  mailbox_ = std::make_unique<tims::Mailbox>(self, 16, 64 * 1024);
  router_.add(*mailbox_);
  endpoint_ = std::make_unique<tims::Endpoint>(router_, *mailbox_, 1);
  // The trace mailbox: small requests only (TRACE_START, TRACE_READ).
  trace_mailbox_ = std::make_unique<tims::Mailbox>(
      Address::make(hs.system, tims::classes::kExecutor, hs.host_id, trace::kTraceMailbox), 8, 1024);
  router_.add(*trace_mailbox_);
  trace_endpoint_ = std::make_unique<tims::Endpoint>(router_, *trace_mailbox_, 1);
}

// The log service: this process's hub, its LCM publisher and the GDOS thread.
void Executor::start_gdos(const std::string& url, Address self) {
  const HostSettings& hs = host_->settings;
  log_source_.set_identity(self.component(), "rackd");
  gdos::Hub::set_process_hub(&hub_);
  if (hs.lcm && hs.gdos.lcm && !url.empty()) {
    step("joining the GDOS network");
    tims::GdosPublisherConfig pc;
    pc.url = hs.gdos.lcm_url.empty() ? url : hs.gdos.lcm_url;
    pc.channel = hs.gdos.channel;
    pc.host = hs.host;
    pc.pid = static_cast<int32_t>(getpid());
    // On a keyed host the log is signed with the first network's key (the gdos viewer
    // verifies it with --key-file).
    if (!hs.networks.empty()) pc.key_file = hs.networks.front().key_file;
    gdos_publisher_ = std::make_unique<tims::GdosPublisher>(pc);
  }
  gdos_running_ = true;
  {
    const HousekeepingAffinity housekeeping(views_, host_->settings);
    gdos_thread_ = std::thread([this] { gdos_loop(); });
  }
}

// Access control (the host file's `access:`), before any component is attached: no
// message slips past the rules.
void Executor::install_access(Address self) {
  const HostSettings& hs = host_->settings;
  if (hs.access_configured) {
    // rackd itself (its endpoint: autostart ON, OFF at shutdown; the transport's
    // STOP_CONT_DATA for lost hosts) is always allowed: a rule of its own, first,
    // matching only messages sent inside this process.
    tims::AccessConfig ac = hs.access;
    tims::AccessRuleConfig own;
    own.name = "rackd";
    own.to.push_back({0, 0});
    own.from.push_back({self.raw(), 0xFFFFFFFFu});
    own.from.push_back({tims::kTransportControlAddress.raw(), 0xFFFFFFFFu});
    own.only_local = true;
    ac.rules.insert(ac.rules.begin(), own);
    {
      // The GDOS thread already runs and reads access_ in gdos_pass(), under this mutex.
      auto access = std::make_unique<tims::AccessControl>(ac);
      std::lock_guard lock(gdos_mutex_);
      access_ = std::move(access);
    }
    router_.set_access(access_.get());
    log(gdos::Level::kInfo, "access control: " + std::to_string(access_->rule_count()) + " rule(s), default " +
                                (access_->default_policy() == tims::AccessDefault::kClosed ? "closed" : "open"));
  } else {
    log(gdos::Level::kWarning,
        "access control: the host file has no 'access:' section: every source may send "
        "every message to every component here (see configs/access_control.yaml)");
  }
}

void Executor::attach_components() {
  const HostSettings& hs = host_->settings;
  for (auto& v : views_) {
    // Before its tasks start: GET_TASKS reads it from the command task.
    fill_host_networks(v.component->host_networks_, hs, first_network_url(hs, options_.lcm_url_override));
    v.component->attach(router_);
    v.attached = true;
  }
}

// init() of each component, in the host file's order; one that fails is in ERROR.
void Executor::init_components() {
  // Threads a library starts in init() (OpenCV's, PCL's pools) are not real-time:
  // they inherit the housekeeping CPUs.
  const HousekeepingAffinity housekeeping(views_, host_->settings);
  for (auto& v : views_) {
    step("init() of component '" + v.component->name() + "'");
    v.init_called = true;
    if (!v.component->run_init(v.init_error)) {
      log(gdos::Level::kError, "component '" + v.component->name() + "' " + v.component->address().str() +
                                   " is in ERROR: init() failed: " + v.init_error);
    }
  }
}

// The I/O workers that components declared in init() (Component::add_io_worker):
// non-RT threads of the executor, on the housekeeping CPUs, each with a log ring.
void Executor::start_io_workers() {
  const HostSettings& hs = host_->settings;
  // Unpartitioned: off the CPUs that RT tasks are pinned to (threads inherit it).
  const HousekeepingAffinity housekeeping(views_, hs);
  for (auto& v : views_) {
    Component& c = *v.component;
    if (!v.init_called || c.init_failed_) continue;
    for (const auto& w : c.io_workers_) {
      step("starting I/O worker '" + w.name + "' of component '" + c.name() + "'");
      auto worker = std::make_unique<IoWorkerThread>();
      worker->stop = w.stop;
      IoWorkerThread* self = worker.get();
      gdos::LogRing* ring = &hub_.make_ring(hs.gdos.ring, c.name() + " I/O worker " + w.name);
      io_workers_.push_back(std::move(worker));
      (void)self->thread.start(
          {w.name, 0, -1, 256 * 1024, hs.housekeeping_cpus},
          [this, self, ring, &c, body = w.body, name = w.name] {
            self->tid.store(static_cast<pid_t>(::syscall(SYS_gettid)), std::memory_order_release);
            gdos::bind_thread_ring(ring);
            std::string failure;
            try {
              body();
            } catch (const std::exception& e) {
              failure = e.what();
            } catch (...) {
              failure = "unknown exception";
            }
            if (!failure.empty()) {
              hub_.publish_text(gdos::Level::kError, c.address(), c.name(),
                                "I/O worker '" + name + "' ended: " + failure);
            }
          },
          false);
      // Its id for thread_report(): the worker sets it first thing (bounded wait). On the
      // kernel's clock: waiting for a real thread is not time passing on a stepped
      // executor's virtual clock (rt::sleep_for moved it up to 1 s here).
      for (int i = 0; i < 1000 && self->tid.load(std::memory_order_acquire) == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
  }
}

// The compute workers that components declared in init() (Component::add_compute_worker):
// each serves its component's data task, which waits for it, so it runs with that
// task's priority and on its CPUs (component.h), with a log ring of its own. Started
// before the tasks, so that the first cycle finds it serving.
void Executor::start_compute_workers() {
  // Stepped (stepper.h): no thread serves them, so each job runs inside the step that
  // posts it, on the stepping thread, when the data task waits for it (ComputeWorker::
  // wait() runs it through ComputeWorker::run, the call a serving thread makes). A
  // thread here would also move the virtual clock while start-up waits for its id.
  if (options_.stepped) return;
  const HostSettings& hs = host_->settings;
  for (auto& v : views_) {
    Component& c = *v.component;
    if (!v.init_called || c.init_failed_) continue;
    const ComponentSettings& s = c.settings();
    const TaskSettings& t = c.data_task_mode() != DataTaskMode::kNone ? s.data_task : s.command_task;
    for (auto& w : c.compute_workers_) {
      step("starting compute worker '" + w.name + "' of component '" + c.name() + "'");
      auto worker = std::make_unique<IoWorkerThread>();
      ComputeWorker* served = w.worker.get();
      worker->stop = [served] { served->stop(); };
      worker->priority = t.priority;
      IoWorkerThread* self = worker.get();
      gdos::LogRing* ring = &hub_.make_ring(hs.gdos.ring, c.name() + " compute worker " + w.name);
      compute_workers_.push_back(std::move(worker));
      // The data task's placement: its `cpu:`, else (partitioned) the RT CPUs for an RT
      // task and the housekeeping CPUs for a non-RT one, else any CPU.
      const std::vector<int> cpus = t.cpu >= 0       ? std::vector<int>{}
                                    : t.priority > 0 ? hs.rt_cpus
                                                     : hs.housekeeping_cpus;
      const auto how = self->thread.start(
          {c.name().substr(0, 10) + ":" + w.name, t.priority, t.cpu, 256 * 1024, cpus},
          [self, ring, served] {
            self->tid.store(static_cast<pid_t>(::syscall(SYS_gettid)), std::memory_order_release);
            gdos::bind_thread_ring(ring);
            served->serve();
          },
          options_.allow_rt_fallback);
      fallback_ = fallback_ || how == rt::ThreadStart::kFallback;
      if (t.cpu >= 0) {
        log(gdos::Level::kWarning, "component '" + c.name() + "': compute worker '" + w.name +
                                       "' shares the data task's one CPU (cpu: " + std::to_string(t.cpu) +
                                       "): no parallel work; give the data task no cpu: to let it use two");
      }
      for (int i = 0; i < 1000 && self->tid.load(std::memory_order_acquire) == 0; ++i) rt::sleep_for(rt::kNsPerMs);
    }
  }
}

// Stops every I/O worker (its stop function) and joins it; after the tasks ended.
void Executor::stop_io_workers() noexcept {
  for (auto& w : io_workers_) {
    if (!w->thread.joinable()) continue;
    try {
      w->stop();
    } catch (...) {
      // A stop function that throws: the join below waits for the body as it is.
    }
    w->thread.join();
  }
  io_workers_.clear();
  for (auto& w : compute_workers_) {
    if (!w->thread.joinable()) continue;
    w->stop();  // ComputeWorker::stop: noexcept
    w->thread.join();
  }
  compute_workers_.clear();
}

// The command task and (if it has one) the data task of one component, with the
// priority, CPU and stack of the host file.
void Executor::start_tasks(ComponentView& v) {
  if (options_.stepped) return add_stepped_task(v);
  const HostSettings& hs = host_->settings;
  Component& c = *v.component;
  const ComponentSettings& s = c.settings();
  // Each task registers itself with the mode-switch detector (a no-op when
  // rackd did not start it) before its first cycle.
  auto watch = [&](const TaskSettings& t, const char* suffix) {
    // A priority-0 task runs with normal scheduling: it is not real-time, so what it
    // does (MCL allocates every update) is not a mode switch unless asked for.
    const auto fallback = t.priority == 0 ? rt::modeswitch::Mode::kOff : hs.modeswitch.default_mode;
    return rt::modeswitch::TaskInfo{c.name() + suffix, c.name(), c.address().str(), c.address().raw(),
                                    t.modeswitch.value_or(fallback)};
  };
  // Partitioned (`cpus:`): a task without its own `cpu:` runs on the RT CPUs when
  // it is real-time, on the housekeeping CPUs when it is not.
  auto task_cpus = [&hs](const TaskSettings& t) {
    return t.cpu >= 0 ? std::vector<int>{} : t.priority > 0 ? hs.rt_cpus : hs.housekeeping_cpus;
  };
  // One task's thread: its trace ring and GDOS ring, registered with the mode-switch
  // detector before `run`'s first cycle; the start-up ends at faults.mark_started().
  auto start_task = [&](const char* kind, const std::string& thread_name, const TaskSettings& t, const char* suffix,
                        rt::TaskFaults& faults, std::function<void()> run) {
    auto* ring = trace_rings_.emplace_back(std::make_unique<rt::trace::Ring>(hs.trace_ring_events)).get();
    trace_.add_task(c.name() + " " + kind, c.name(), c.address().raw(), ring);
    auto thread = std::make_unique<rt::Thread>();
    gdos::LogRing* log_ring = &hub_.make_ring(hs.gdos.ring, c.name() + " " + kind);
    const auto how = thread->start(
        {thread_name, t.priority, t.cpu, t.stack_bytes, task_cpus(t)},
        [log_ring, ring, &faults, run = std::move(run), info = watch(t, suffix)] {
          gdos::bind_thread_ring(log_ring);
          rt::trace::bind_thread_ring(ring);
          rt::modeswitch::TaskAttachment attach(info);
          faults.mark_started();  // start-up ends here
          run();
        },
        options_.allow_rt_fallback);
    fallback_ = fallback_ || how == rt::ThreadStart::kFallback;
    threads_.push_back(std::move(thread));
    return how;
  };
  const auto how = start_task("command task", c.name().substr(0, 11) + ":cmd", s.command_task, ":cmd",
                              c.command_faults_, [&c] { c.run_command_task(); });
  v.realtime = how == rt::ThreadStart::kRealTime;
  v.tasks_started = true;
  if (auto* dc = dynamic_cast<DataComponentBase*>(&c); dc != nullptr && c.data_task_mode() != DataTaskMode::kNone) {
    (void)start_task("data task", c.name().substr(0, 10) + ":data", s.data_task, ":data", c.data_faults_,
                     [dc] { dc->run_data_task(); });
  }
}

// Joins the host's TiMS network (LCM) and announces this host's components.
void Executor::join_network(const std::string& url, Address self) {
  const HostSettings& hs = host_->settings;
  if (hs.lcm && (!url.empty() || !hs.networks.empty())) {
    step("joining the TiMS network " + url);
    tims::LcmTransportConfig tc;
    tc.url = url;
    tc.networks = hs.networks;
    // --lcm replaces the first network's URL (tests and one-off runs).
    if (!tc.networks.empty() && !options_.lcm_url_override.empty()) tc.networks.front().url = url;
    tc.role = hs.role;
    tc.announce_period_ns = hs.announce_period_ns;
    tc.expiry_ns = hs.expiry_ns;
    tc.max_message_bytes = hs.max_message_bytes;
    tc.large_slots = hs.large_slots;
    tc.receive_priority = hs.receive_priority;
    tc.warn = [this](const std::string& s) { log(gdos::Level::kWarning, s); };
    const HousekeepingAffinity housekeeping(views_, host_->settings);  // the transport's threads
    tc.replay_window_ns = hs.replay_window_ns;
    transport_ = std::make_unique<tims::LcmTransport>(router_, tc);
    // Other hosts of this robot own the rest of its addresses: let the transport
    // decide (discovery) instead of answering NOT_AVAILABLE here.
    router_.set_system_shared(true);
    tims::HostInfo info;
    info.host = hs.host;
    info.system = hs.system;
    info.host_id = hs.host_id;
    info.role = hs.role;
    info.pid = static_cast<int32_t>(getpid());
    info.executor = self.component();
    for (const auto& v : views_) {
      info.components.push_back({v.component->address(), v.component->name(), v.component->settings().impl});
    }
    transport_->set_announcement(std::move(info));
    transport_->start();
    // Autostarted components subscribe to other hosts: let discovery fill first
    // (in steps, so that a stop request is not kept waiting). Only when one of
    // them refers to a component that is not on this host: a host whose references
    // are all its own (configs/demo.yaml) switches them on at once.
    bool remote_refs = false;
    for (const auto& v : views_) {
      if (!v.component->settings().autostart) continue;
      for (const auto& [param, target] : v.component->refs_) {
        const bool local = std::any_of(views_.begin(), views_.end(), [&t = target](const auto& w) {
          return w.component->address().component() == t.component();
        });
        remote_refs = remote_refs || !local;
      }
    }
    if (remote_refs) {
      for (const int64_t warm_at = rt::monotonic_ns() + tc.warmup_ns; rt::monotonic_ns() < warm_at;) {
        step("waiting for the other hosts' announcements");
        rt::sleep_for(10 * rt::kNsPerMs);
      }
      transport_->wait_until_warm();
    }
  }
}

// The trace thread (TRACE_START, TRACE_READ on mailbox #2).
void Executor::start_trace_thread() {
  const HostSettings& hs = host_->settings;
  trace_.format().pid = static_cast<int>(getpid());
  trace_.format().process_name = "rackd host '" + hs.host + "'";
  // Names of this host's components by address (the rest: TiMS's own spelling).
  std::vector<std::pair<uint32_t, std::string>> names;
  for (const auto& v : views_) names.emplace_back(v.component->address().raw(), v.component->name());
  trace_.format().address_name = [names](uint32_t raw) {
    const Address a(raw);
    for (const auto& [addr, name] : names) {
      if (addr == a.component().raw()) return name + (a.raw() == addr ? "" : "#" + std::to_string(a.raw() & 0xFFu));
    }
    return a.str();
  };
  const HousekeepingAffinity housekeeping(views_, host_->settings);
  trace_thread_ = std::thread([this] { trace_loop(); });
}

void Executor::log_started() {
  const HostSettings& hs = host_->settings;
  std::size_t realtime = 0;
  for (const auto& v : views_) realtime += v.realtime ? 1 : 0;
  log(gdos::Level::kInfo,
      "host '" + hs.host + "' started " + std::to_string(views_.size()) + " component(s), " + std::to_string(realtime) +
          " with SCHED_FIFO tasks" + (transport_ ? ", TiMS on " + transport_->url() : std::string(", no LCM")) +
          (gdos_publisher_ ? ", GDOS on " + gdos_publisher_->url() + " channel " + hs.gdos.channel : std::string()));
}

// ON to every component marked autostart, in the host file's (dependency) order.
void Executor::autostart_components() {
  for (auto& v : views_) {
    Component& c = *v.component;
    if (!c.settings().autostart) continue;
    step("switching on component '" + c.name() + "' (autostart)");
    std::string why;
    if (!send_command(c, msg::kOn, c.settings().rpc_timeout_ns * 4, why)) {
      log(gdos::Level::kWarning, "autostart of '" + c.name() + "' " + c.address().str() + " failed: " + why +
                                     " (it retries every " + std::to_string(c.settings().retry_ns / rt::kNsPerMs) +
                                     " ms)");
    }
  }
}

void Executor::stop() {
  if (!started_) return;
  started_ = false;
  // OFF in reverse dependency order: consumers before their producers.
  if (endpoint_) {
    for (auto it = views_.rbegin(); it != views_.rend(); ++it) {
      Component& c = *it->component;
      if (!it->tasks_started || c.state() == ComponentState::kDisabled) continue;
      std::string why;
      if (!send_command(c, msg::kOff, c.settings().rpc_timeout_ns, why)) {
        log(gdos::Level::kError, "OFF of '" + c.name() + "' failed: " + why);
      }
    }
  }
  for (auto& v : views_) v.component->request_stop();
  for (auto& t : threads_) t->join();
  threads_.clear();
  stepped_.clear();
  stop_io_workers();
  if (trace_mailbox_) {
    trace_mailbox_->close();
    if (trace_thread_.joinable()) trace_thread_.join();
    router_.remove(trace_mailbox_->address());
  }
  if (transport_) transport_->stop();
  for (auto it = views_.rbegin(); it != views_.rend(); ++it) {
    if (it->init_called) it->component->run_cleanup();
  }
  for (auto& v : views_) {
    if (v.attached) v.component->detach();
  }
  if (mailbox_) router_.remove(mailbox_->address());
  router_.set_access(nullptr);
  const auto c = hub_.counters();
  if (c.dropped > 0) {
    log(gdos::Level::kWarning, "GDOS: " + std::to_string(c.dropped) + " log record(s) were dropped in full rings");
  }
  // Last: the GDOS thread drains what the shutdown logged, then ends.
  {
    std::lock_guard lock(gdos_mutex_);
    gdos_running_ = false;
  }
  gdos_cv_.notify_all();
  if (gdos_thread_.joinable()) gdos_thread_.join();
  gdos_publisher_.reset();
  if (gdos::Hub::process_hub() == &hub_) gdos::Hub::set_process_hub(nullptr);
  if (placing_threads_) rt::thread_birth::stop_placing();
  placing_threads_ = false;
}

void Executor::trace_loop() {
  pthread_setname_np(pthread_self(), "rackd:trace");  // not RT: SCHED_OTHER, housekeeping CPUs
  alignas(8) std::byte buf[1024];
  for (;;) {
    // 10 ms while recording: a ring of 4096 events (trace_ring_events' default) never
    // fills below ~400 events/ms. Otherwise it sleeps until a request comes (or stop()
    // closes the mailbox): an idle executor's trace thread does not wake at all.
    const int64_t wait = trace_.state() == trace::TraceState::kRecording ? 10 * rt::kNsPerMs : tims::Mailbox::kForever;
    const auto r = trace_mailbox_->receive(std::span<std::byte>(buf), wait);
    if (r.status == tims::RecvStatus::kClosed) break;
    try {
      if (r.status == tims::RecvStatus::kOk) {
        trace_request(r.header, std::span<const std::byte>(buf + sizeof(tims::MessageHeader),
                                                           r.length - sizeof(tims::MessageHeader)));
      } else if (r.status == tims::RecvStatus::kTooSmall && r.header.is_request()) {
        wire::ErrorText e;
        wire::copy_text(e.text, "trace request larger than 1 KiB");
        const tims::ConstBuffer part = tims::buffer_of(e);
        (void)trace_endpoint_->reply(r.header, msg::kError, std::span<const tims::ConstBuffer>(&part, 1));
      }
      trace_.poll(rt::monotonic_ns());
    } catch (const std::exception& e) {  // out of memory while collecting or formatting
      log(gdos::Level::kError, std::string("trace: ") + e.what() + "; the trace is discarded");
      trace_ = trace::TraceSession();
    }
  }
  trace_.finish(rt::monotonic_ns());
}

void Executor::trace_request(const tims::MessageHeader& h, std::span<const std::byte> body) {
  const auto error = [&](const std::string& why) {
    wire::ErrorText e;
    wire::copy_text(e.text, why.c_str());
    const tims::ConstBuffer part = tims::buffer_of(e);
    (void)trace_endpoint_->reply(h, msg::kError, std::span<const tims::ConstBuffer>(&part, 1));
  };
  if (!h.is_request()) return;  // replies and notifications: never answered
  // A body in the other byte order (a big-endian rackctl): its integers are swapped.
  const bool swapped = ((h.flags & tims::kFlagBodyLittleEndian) != 0) != tims::kHostLittleEndian;
  if (h.type == trace::kTraceStart) {
    const trace::DecodedStart req = trace::decode_start(body, swapped);
    if (!req.ok) {
      error(req.error);
      return;
    }
    const int64_t duration = req.duration_ns;
    trace::TraceStartReply reply;
    const std::string why = trace_.start(req.names, duration, rt::monotonic_ns(), reply.tasks);
    if (!why.empty()) {
      error(why);
      return;
    }
    log(gdos::Level::kInfo, "trace: recording " + std::to_string(reply.tasks) + " task(s) for " +
                                std::to_string(duration / rt::kNsPerMs) + " ms for " + h.source().str());
    const tims::ConstBuffer part = tims::buffer_of(reply);
    (void)trace_endpoint_->reply(h, msg::kOk, std::span<const tims::ConstBuffer>(&part, 1));
    return;
  }
  if (h.type == trace::kTraceRead) {
    const trace::DecodedRead req = trace::decode_read(body, swapped);
    if (!req.ok) {
      error(req.error);
      return;
    }
    const uint64_t offset = req.offset;
    trace_.poll(rt::monotonic_ns());
    trace::TraceChunkHeader head;
    head.state = static_cast<uint32_t>(trace_.state());
    head.remaining_ns = trace_.remaining_ns(rt::monotonic_ns());
    head.dropped = trace_.dropped();
    const std::string& json = trace_.json();
    if (trace_.state() == trace::TraceState::kReady) {
      head.total = json.size();
      if (offset > json.size()) {
        error("TRACE_READ: offset " + std::to_string(offset) + " is past the end of the trace (" +
              std::to_string(json.size()) + " bytes)");
        return;
      }
      head.offset = offset;
      head.length = static_cast<uint32_t>(std::min<uint64_t>(trace::kTraceChunkBytes, json.size() - offset));
    }
    const tims::ConstBuffer parts[2] = {tims::buffer_of(head),
                                        {reinterpret_cast<const std::byte*>(json.data()) + head.offset, head.length}};
    (void)trace_endpoint_->reply(h, msg::kOk, std::span<const tims::ConstBuffer>(parts, 2));
    return;
  }
  error("unknown request " + std::to_string(h.type) + " for the trace mailbox (TRACE_START 21, TRACE_READ 22)");
}

std::string Executor::status_report() const {
  std::string out;
  for (const auto& v : views_) {
    const Component& c = *v.component;
    c.sample_faults();
    wire::StatsReply s;
    c.fill_stats(s);
    char line[512];
    if (c.data_task_mode() == DataTaskMode::kPeriodic) {
      std::snprintf(line, sizeof line,
                    "  %-14s %-15s %-8s cycles %-7llu overruns %-3llu wake-up p50 %lld us p99 %lld us max %lld us, "
                    "published %llu, listeners %llu\n",
                    c.name().c_str(), c.address().str().c_str(), describe(c.state()),
                    static_cast<unsigned long long>(s.data.cycles), static_cast<unsigned long long>(s.data.overruns),
                    static_cast<long long>(s.data.latency_p50_ns / 1000),
                    static_cast<long long>(s.data.latency_p99_ns / 1000),
                    static_cast<long long>(s.data.latency_max_ns / 1000), static_cast<unsigned long long>(s.published),
                    static_cast<unsigned long long>(s.listeners));
    } else if (c.data_task_mode() == DataTaskMode::kTriggered) {
      std::snprintf(line, sizeof line, "  %-14s %-15s %-8s cycles %-7llu (triggered), published %llu, listeners %llu\n",
                    c.name().c_str(), c.address().str().c_str(), describe(c.state()),
                    static_cast<unsigned long long>(s.data.cycles), static_cast<unsigned long long>(s.published),
                    static_cast<unsigned long long>(s.listeners));
    } else {
      std::snprintf(line, sizeof line, "  %-14s %-15s %-8s commands %llu\n", c.name().c_str(),
                    c.address().str().c_str(), describe(c.state()), static_cast<unsigned long long>(s.commands));
    }
    out += line;
    if (s.exec_samples > 0) {  // how long loop() ran, periodic and triggered alike
      std::snprintf(line, sizeof line, "      execution time p50 %.1f us p99 %.1f us max %.1f us (%llu cycles)\n",
                    static_cast<double>(s.exec_p50_ns) / 1e3, static_cast<double>(s.exec_p99_ns) / 1e3,
                    static_cast<double>(s.exec_max_ns) / 1e3, static_cast<unsigned long long>(s.exec_samples));
      out += line;
    }
    // Page faults since each task's start-up (target 0 for an RT task); "-" when not
    // measured (the task has not started). Parsed by bench/run: keep the format.
    {
      const auto faults = [](const rt::TaskFaults& f, int priority) {
        const rt::FaultCount n = f.last();
        char part[96];
        if (!n.measured) return std::string("-");
        std::snprintf(part, sizeof part, "%llu minor %llu major (%s)", static_cast<unsigned long long>(n.minor),
                      static_cast<unsigned long long>(n.major), priority > 0 ? "RT" : "not RT");
        return std::string(part);
      };
      std::string fl = "      page faults after start-up: command task " +
                       faults(c.command_task_faults(), c.settings().command_task.priority);
      if (c.data_task_mode() != DataTaskMode::kNone) {
        fl += ", data task " + faults(c.data_task_faults(), c.settings().data_task.priority);
      }
      out += fl + "\n";
    }
    std::string extra;
    c.describe_status(extra);
    if (!extra.empty()) out += "      " + extra + "\n";
  }
  {
    const auto g = hub_.counters();
    char line[256];
    std::snprintf(line, sizeof line, "  GDOS: records %llu, dropped in full rings %llu",
                  static_cast<unsigned long long>(g.records), static_cast<unsigned long long>(g.dropped));
    out += line;
    if (gdos_publisher_) {
      const auto p = gdos_publisher_->counters();
      std::snprintf(line, sizeof line,
                    ", published %llu in %llu batches, publish errors %llu, listener messages refused %llu",
                    static_cast<unsigned long long>(p.records), static_cast<unsigned long long>(p.batches),
                    static_cast<unsigned long long>(p.publish_errors), static_cast<unsigned long long>(p.refused));
      out += line;
    }
    out += '\n';
  }
  if (transport_) {
    const auto t = transport_->counters();
    char line[512];
    const auto u = [](uint64_t x) { return static_cast<unsigned long long>(x); };
    std::snprintf(line, sizeof line,
                  "  TiMS/LCM: packets in %llu out %llu, malformed %llu, forged %llu, auth failed %llu, replayed %llu, "
                  "undeliverable %llu, sequence gaps %llu, lost %llu, forwarded %llu, not available %llu, hosts %zu, "
                  "expired %llu, subscriptions failed %llu\n",
                  u(t.packets_in), u(t.packets_out), u(t.malformed), u(t.forged), u(t.auth_failed), u(t.replayed),
                  u(t.delivery_failed), u(t.sequence_gaps), u(t.lost_messages), u(t.forwarded), u(t.not_available),
                  transport_->hosts().size(), u(t.hosts_expired), u(t.subscriptions_failed));
    out += line;
    // What was refused, by kind (README: "What the network may not do"); parsed by tests.
    std::snprintf(line, sizeof line,
                  "  TiMS/LCM refused: lcm framing %llu, lcm fragments %llu, tims packets %llu, announcements %llu, "
                  "discovers %llu, hosts over the limit %llu; discovers answered %llu, coalesced %llu\n",
                  u(t.malformed_lcm), u(t.lcm_fragments), u(t.malformed_packet), u(t.malformed_announce),
                  u(t.malformed_discover), u(t.hosts_refused), u(t.discovers_answered), u(t.discovers_suppressed));
    out += line;
  }
  if (access_) out += access_->status_text();
  return out;
}

}  // namespace rack

namespace rack {

namespace {

std::vector<pid_t> own_threads() {
  std::vector<pid_t> out;
  DIR* d = opendir("/proc/self/task");
  if (d == nullptr) return out;
  while (const dirent* e = readdir(d)) {
    char* end = nullptr;
    const long tid = std::strtol(e->d_name, &end, 10);
    if (tid > 0 && end != nullptr && *end == '\0') out.push_back(static_cast<pid_t>(tid));
  }
  closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

std::string thread_name(pid_t tid) {
  std::ifstream in("/proc/self/task/" + std::to_string(tid) + "/comm");
  std::string name;
  std::getline(in, name);
  return name.empty() ? "?" : name;
}

std::vector<int> thread_cpus(pid_t tid) {
  std::vector<int> out;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(tid, sizeof set, &set) != 0) return out;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(static_cast<std::size_t>(c), &set)) out.push_back(c);
  }
  return out;
}

bool contains(const std::vector<int>& v, int c) { return std::find(v.begin(), v.end(), c) != v.end(); }

}  // namespace

std::string Executor::thread_report() const {
  const HostSettings& hs = host_->settings;
  struct Task {
    pid_t tid;
    std::string what;
  };
  std::vector<Task> tasks;
  for (const auto& v : views_) {
    if (!v.tasks_started) continue;
    const Component& c = *v.component;
    const ComponentSettings& s = c.settings();
    tasks.push_back({c.command_task_faults().tid(), s.command_task.priority > 0 ? "RT task" : "task, not RT"});
    if (c.data_task_mode() != DataTaskMode::kNone) {
      tasks.push_back({c.data_task_faults().tid(), s.data_task.priority > 0 ? "RT task" : "task, not RT"});
    }
  }
  std::string out;
  if (hs.housekeeping_cpus.empty()) {
    out += "threads (no partitioning: no 'cpus:' in the host file)\n";
  } else {
    out += "threads (cpus: rt " + rt::cpu_list_string(hs.rt_cpus) + ", housekeeping " +
           rt::cpu_list_string(hs.housekeeping_cpus) + ")\n";
  }
  for (const pid_t tid : own_threads()) {
    const int policy = sched_getscheduler(tid);
    sched_param param{};
    (void)sched_getparam(tid, &param);
    std::string sched = policy == SCHED_FIFO ? "FIFO " + std::to_string(param.sched_priority)
                        : policy == SCHED_RR ? "RR " + std::to_string(param.sched_priority)
                                             : "OTHER";
    std::string role = "housekeeping";
    if (tid == getpid()) role = "housekeeping (main)";
    for (const auto& w : io_workers_) {
      if (w->tid.load(std::memory_order_acquire) == tid) role = "I/O worker, not RT";
    }
    for (const auto& w : compute_workers_) {
      if (w->tid.load(std::memory_order_acquire) == tid) {
        role = w->priority > 0 ? "compute worker, RT" : "compute worker, not RT";
      }
    }
    for (const auto& t : tasks) {
      if (t.tid == tid) role = t.what;
    }
    char line[160];
    std::snprintf(line, sizeof line, "  %7d  %-15s  %-8s  CPUs %-8s  %s\n", static_cast<int>(tid),
                  thread_name(tid).c_str(), sched.c_str(), rt::cpu_list_string(thread_cpus(tid)).c_str(), role.c_str());
    out += line;
  }
  return out;
}

std::vector<std::string> Executor::partition_threads() {
  std::vector<std::string> moved;
  const HostSettings& hs = host_->settings;
  if (hs.housekeeping_cpus.empty() || !started_) return moved;
  std::vector<pid_t> tasks;
  for (const auto& v : views_) {
    if (!v.tasks_started) continue;
    const Component& c = *v.component;
    tasks.push_back(c.command_task_faults().tid());
    if (c.data_task_mode() != DataTaskMode::kNone) tasks.push_back(c.data_task_faults().tid());
  }
  // Compute workers run where their data task runs (start_compute_workers): not moved.
  for (const auto& w : compute_workers_) tasks.push_back(w->tid.load(std::memory_order_acquire));
  // A task that has not marked its start-up yet cannot be told from a helper thread:
  // try again at the next call rather than move an RT task.
  if (std::find(tasks.begin(), tasks.end(), 0) != tasks.end()) return moved;
  // Read before the listing: a thread born during the pass changes the count again.
  swept_thread_count_ = rt::process_thread_count();
  for (const pid_t tid : own_threads()) {
    if (std::find(tasks.begin(), tasks.end(), tid) != tasks.end()) continue;
    std::string what;
    if (thread_cpus(tid) != hs.housekeeping_cpus && rt::set_thread_affinity(tid, hs.housekeeping_cpus) == 0) {
      what = "moved to the housekeeping CPUs";
    }
    // A thread that an RT task (or a library it called) started inherits its
    // SCHED_FIFO priority as well as its CPUs: it is not an RT task, and at that
    // priority it would hold up housekeeping (the transport, GDOS).
    const int policy = sched_getscheduler(tid);
    if (policy == SCHED_FIFO || policy == SCHED_RR) {
      sched_param was{};
      (void)sched_getparam(tid, &was);
      const sched_param other{};
      if (sched_setscheduler(tid, SCHED_OTHER, &other) == 0) {
        what += std::string(what.empty() ? "" : ", ") + (policy == SCHED_FIFO ? "SCHED_FIFO " : "SCHED_RR ") +
                std::to_string(was.sched_priority) + " (inherited) lowered to SCHED_OTHER";
      }
    }
    if (!what.empty()) moved.push_back(std::to_string(tid) + " (" + thread_name(tid) + "): " + what);
  }
  return moved;
}

std::vector<std::string> Executor::partition_new_threads() {
  if (host_->settings.housekeeping_cpus.empty() || !started_) return {};
  const long count = rt::process_thread_count();
  if (count > 0 && count == swept_thread_count_) return {};
  return partition_threads();
}

std::vector<std::string> Executor::partition_warnings() const {
  std::vector<std::string> out;
  const HostSettings& hs = host_->settings;
  if (hs.housekeeping_cpus.empty()) return out;
  std::vector<int> both;
  for (const int c : hs.rt_cpus) {
    if (contains(hs.housekeeping_cpus, c)) both.push_back(c);
  }
  if (!both.empty()) {
    out.push_back("cpus: CPU " + rt::cpu_list_string(both) +
                  " serves RT tasks and housekeeping alike: the GDOS, network and library threads there delay "
                  "the RT tasks' wake-ups");
  }
  for (const auto& v : views_) {
    const Component& c = *v.component;
    const ComponentSettings& s = c.settings();
    const auto check = [&](const TaskSettings& t, const char* which) {
      if (t.cpu < 0) return;
      if (t.priority > 0 && !contains(hs.rt_cpus, t.cpu)) {
        out.push_back("cpus: " + c.name() + "'s " + which + " (RT, priority " + std::to_string(t.priority) +
                      ") is pinned to CPU " + std::to_string(t.cpu) + ", not one of the RT CPUs " +
                      rt::cpu_list_string(hs.rt_cpus));
      } else if (t.priority == 0 && contains(hs.rt_cpus, t.cpu)) {
        out.push_back("cpus: " + c.name() + "'s " + which + " (not RT) is pinned to RT CPU " + std::to_string(t.cpu));
      }
    };
    check(s.command_task, "command task");
    if (c.data_task_mode() != DataTaskMode::kNone) check(s.data_task, "data task");
  }
  return out;
}

}  // namespace rack
