// The executor: runs the components of one host. rackd is a thin main around it;
// tests use it in-process.
//
// start(): attach every component to the router (mailboxes), init() each (non-RT;
// an init() that throws leaves that component in ERROR and nothing else), start the
// command and data tasks with the priority, CPU and stack from the host file, join
// the LCM network, then switch on the components marked autostart (dependencies
// first). stop(): OFF in reverse dependency order, stop and join every task,
// cleanup() each, leave the network.
//
// GDOS: every task gets its own log ring (gdos.ring records) bound to its thread;
// one non-RT thread (the GDOS thread) drains them every gdos.drain_ms, formats the
// records and writes them to stderr (gdos.stderr) and publishes them on LCM
// (gdos.lcm_url, channel gdos.channel). Executor events (start, init failures, ON,
// OFF, ERROR, overruns, autostart failures) go the same way.
//
// I/O workers: blocking device I/O that a component declared in init()
// (Component::add_io_worker) runs in a non-RT thread of the executor on the
// housekeeping CPUs, started after init(), stopped and joined after the tasks.
// Compute workers (Component::add_compute_worker, rack/core/compute_worker.h): a
// second thread for a data task's bulk computation, with that task's priority and
// CPUs, started after init() and before the tasks, stopped and joined with the I/O
// workers, before cleanup().
//
// CPUs: the executor's own non-RT threads (GDOS, the TiMS/LCM transport, I/O workers) are kept off
// the CPUs that RT tasks are pinned to (`cpu:`), when another CPU is left. With the
// host file's `cpus:` block (partitioning), RT tasks without a `cpu:` run on its `rt`
// CPUs and everything else (non-RT tasks, the executor's threads, threads libraries
// start: they are born there, rack/rt/thread_birth.h; partition_threads() moves what was
// not) on its `housekeeping` CPUs.
// Page faults: each task marks the end of its start-up; the GDOS thread samples every
// task's faults since then once a second (Component::sample_faults, GET_STATS).
//
// Task timeline: every task records into its own rt::trace::Ring (preallocated at
// start(), the host file's trace_ring_events, 4096 by default; off until a trace is asked for); the trace thread
// (rackd:trace, not RT, on the housekeeping CPUs) answers TRACE_START and TRACE_READ
// on Executor(sys/host_id)#2 (rack/core/trace_session.h, `rackctl trace`).
//
// Stepped (ExecutorOptions::stepped, tests): no task threads; requests are served as
// they are sent and a Stepper runs the data tasks on a virtual clock (rack/core/stepper.h).
//
// Real-time contract: not RT-safe; call from the main (non-RT) thread.
// Thread-safety: start/stop from one thread; status() from any non-RT thread.
#pragma once

#include <atomic>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <string>
#include <vector>

#include "rack/core/data_component.h"
#include "rack/core/gdos.h"
#include "rack/core/host_config.h"
#include "rack/core/trace_session.h"
#include "rack/rt/thread.h"
#include "rack/tims/gdos_lcm.h"
#include "rack/tims/lcm_transport.h"

namespace rack {

// start() was asked to stop (ExecutorOptions::stop_requested) and undid what it had
// started. Not a failure: rackd says it stopped during start-up.
class StartStopped : public std::runtime_error {
 public:
  StartStopped() : std::runtime_error("start-up stopped on request") {}
};

struct ExecutorOptions {
  bool allow_rt_fallback = true;  // run SCHED_OTHER when SCHED_FIFO is refused
  std::string lcm_url_override;   // replaces the host file's lcm_url when not empty
  // Executor events are always logged through GDOS; `log`, when set, also gets
  // each event's text (tests capture them this way).
  std::function<void(const std::string&)> log;
  // Every GDOS record of this host, as the GDOS thread hands it to stderr and LCM
  // (tests, embedders). Called on the GDOS thread (not RT).
  std::function<void(const gdos::Record&)> gdos_sink;
  // Checked by start() between its steps (each component's init(), the tasks, the
  // network, its warm-up, each autostart ON): true makes start() undo what it
  // started and throw StartStopped. rackd sets it on SIGINT/SIGTERM. Main thread.
  std::function<bool()> stop_requested;
  // Told what start() does next ("init() of component 'mcl'"), for rackd's message
  // when a signal comes during start-up. Main thread.
  std::function<void(const std::string&)> phase;
  // Stepped (tests; rack/core/stepper.h): no task threads. The command tasks serve a
  // request in the sender's thread as it is sent, the data tasks run when a Stepper
  // steps them, on the rt::VirtualClock the test installed before start(). For hosts
  // without LCM (`lcm: false`): start() throws std::logic_error for one with LCM.
  bool stepped = false;
};

struct ComponentView {
  Component* component = nullptr;
  bool realtime = false;  // tasks run SCHED_FIFO
  std::string init_error;
  bool attached = false;       // its mailboxes are in the router
  bool init_called = false;    // start() ran its init() (cleanup() runs only then)
  bool tasks_started = false;  // its command task runs (it can answer OFF)
};

struct SteppedTask;  // rack/core/stepper.h

class Executor {
 public:
  Executor(std::unique_ptr<LoadedHost> host, ExecutorOptions options);
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  // Throws std::runtime_error when a task cannot start or the network cannot be
  // joined (the message says which and why), StartStopped when stop_requested said
  // so; what was started is stopped again in both cases.
  void start();
  void stop();  // idempotent

  [[nodiscard]] const HostSettings& settings() const noexcept { return host_->settings; }
  [[nodiscard]] tims::Router& router() noexcept { return router_; }
  [[nodiscard]] const std::vector<ComponentView>& components() const noexcept { return views_; }
  [[nodiscard]] Component* find(const std::string& name_or_address) noexcept;
  // The executor's own endpoint, Executor(sys/host_id)#1: commands from main().
  [[nodiscard]] tims::Endpoint& endpoint() noexcept { return *endpoint_; }
  [[nodiscard]] tims::LcmTransport* transport() noexcept { return transport_.get(); }
  [[nodiscard]] bool any_fallback() const noexcept { return fallback_; }
  // Access control of this host (the host file's `access:`), or nullptr without it.
  [[nodiscard]] tims::AccessControl* access() noexcept { return access_.get(); }

  // One line per component: state, data task cycles/overruns/latency (for rackd).
  [[nodiscard]] std::string status_report() const;

  // Where every thread of this process runs: one line each with its id, name,
  // scheduling, allowed CPUs and role (RT task, normal task, housekeeping), from
  // /proc/self/task. Not RT-safe; any non-RT thread.
  [[nodiscard]] std::string thread_report() const;
  // Partitioning (`cpus:`): moves every thread that is not one of the executor's tasks
  // (library threads started after start(), helpers) onto the housekeeping CPUs, and
  // lowers such a thread's SCHED_FIFO/RR (inherited from the RT task that started it)
  // to SCHED_OTHER. Returns what it did ("1234 (name): moved to the housekeeping
  // CPUs"); none without partitioning, or while a task has not started yet. rackd
  // calls it after start(). Not RT-safe; main thread.
  std::vector<std::string> partition_threads();
  // partition_threads() when the process's thread count (/proc/self/stat, one read)
  // differs from the last complete pass's; else nothing. With rackd's pthread_create
  // (rack/rt/thread_birth.h) threads are born on the housekeeping CPUs, so this is
  // the backstop for those born otherwise (glibc's own helpers, a raw clone(), a
  // sanitizer build): rackd calls it every 100 ms and says what it moved. Not RT-safe;
  // main thread.
  std::vector<std::string> partition_new_threads();
  // What is questionable about the partitioning: an RT CPU that also serves
  // housekeeping, an RT task pinned (`cpu:`) to a housekeeping-only CPU, a non-RT task
  // pinned to an RT CPU. Empty without partitioning. Not RT-safe.
  [[nodiscard]] std::vector<std::string> partition_warnings() const;

  // The non-RT entry point for preformatted reports (mode-switch reports, crash
  // reports): queued to GDOS as a record of `source` (the executor when empty),
  // published with the next pass. Not RT-safe (allocates); any non-RT thread.
  void publish_report(gdos::Level level, const std::string& text, tims::Address source = tims::Address(),
                      const std::string& source_name = {});
  [[nodiscard]] gdos::Hub& gdos_hub() noexcept { return hub_; }
  [[nodiscard]] const gdos::LogSource& log_source() const noexcept { return log_source_; }
  // Formats and hands out what is queued now (the GDOS thread does this every
  // gdos.drain_ms; tests call it to flush). Not RT-safe; any non-RT thread.
  void flush_log();

 private:
  friend class Stepper;
  void log(gdos::Level level, const std::string& line);
  void gdos_pass();
  void pass_guarded() noexcept;
  void gdos_loop();
  bool send_command(Component& c, int8_t type, int64_t timeout_ns, std::string& why);
  // start(), one step each, in this order (start_steps() calls them).
  void start_steps(const std::string& url);
  void open_mailboxes(tims::Address self);
  void start_gdos(const std::string& url, tims::Address self);
  void install_access(tims::Address self);
  void attach_components();
  void init_components();
  void start_io_workers();
  void start_compute_workers();
  void stop_io_workers() noexcept;  // and the compute workers
  void start_tasks(ComponentView& v);
  void add_stepped_task(ComponentView& v);  // ExecutorOptions::stepped: no threads (stepper.cpp)
  void join_network(const std::string& url, tims::Address self);
  void start_trace_thread();
  void log_started();
  void autostart_components();
  void step(const std::string& what);  // phase + stop_requested check (start-up)
  void trace_loop();
  void trace_request(const tims::MessageHeader& h, std::span<const std::byte> body);

  std::unique_ptr<LoadedHost> host_;
  ExecutorOptions options_;
  tims::Router router_;
  std::unique_ptr<tims::Mailbox> mailbox_;
  std::unique_ptr<tims::Endpoint> endpoint_;
  std::unique_ptr<tims::LcmTransport> transport_;
  std::unique_ptr<tims::AccessControl> access_;  // set in start() under gdos_mutex_ (gdos_pass reads it)
  int64_t next_access_report_ns_ = 0;            // GDOS thread: denials are logged at most this often
  std::vector<ComponentView> views_;
  std::vector<std::unique_ptr<rt::Thread>> threads_;
  std::vector<std::unique_ptr<SteppedTask>> stepped_;  // ExecutorOptions::stepped: the tasks without threads
  // The components' I/O workers (Component::add_io_worker): non-RT, housekeeping CPUs;
  // and their compute workers (Component::add_compute_worker): the data task's priority
  // and CPUs.
  struct IoWorkerThread {
    rt::Thread thread;
    std::function<void()> stop;
    std::atomic<pid_t> tid{0};  // set by the worker itself (release; thread_report acquires)
    int priority = 0;           // compute workers: the data task's
  };
  std::vector<std::unique_ptr<IoWorkerThread>> io_workers_;
  std::vector<std::unique_ptr<IoWorkerThread>> compute_workers_;
  bool started_ = false;
  bool fallback_ = false;
  bool placing_threads_ = false;  // start() put rt::thread_birth::place_on() in force
  long swept_thread_count_ = -1;  // threads at the last complete partition_threads()

  gdos::Hub hub_;
  gdos::LogSource log_source_;
  std::unique_ptr<tims::GdosPublisher> gdos_publisher_;
  std::mutex gdos_mutex_;  // one pass at a time; guards gdos_running_ with the cv
  std::condition_variable gdos_cv_;
  bool gdos_running_ = false;
  std::thread gdos_thread_;
  uint64_t gdos_errors_reported_ = 0;  // publish errors already reported
  std::string gdos_out_;               // stderr text of one pass (GDOS thread)
  bool gdos_to_stderr_ = true;         // gdos.stderr: auto: the current choice

  // Task timeline (trace thread only, except the rings, which the tasks write).
  std::vector<std::unique_ptr<rt::trace::Ring>> trace_rings_;
  trace::TraceSession trace_;
  std::unique_ptr<tims::Mailbox> trace_mailbox_;
  std::unique_ptr<tims::Endpoint> trace_endpoint_;
  std::thread trace_thread_;
};

}  // namespace rack
