// RACK's component: a command task that serves its command mailbox, hooks that a
// component class overrides, runtime parameters, and the DISABLED/ENABLED/ERROR
// life cycle. The framework owns the loops; a class overrides hooks (STYLE.md 1).
//
// Life cycle (all transitions run in the command task):
//
//   DISABLED --ON, on() ok----------------> ENABLED    ON answered OK when on() returns
//   DISABLED --ON, on() fails or throws---> ERROR      ON answered ERROR
//   ERROR ----back-off elapsed, on() ok---> ENABLED    (retry; no one is answered)
//   ERROR ----back-off elapsed, fails-----> ERROR      next back-off
//   ERROR ----ON--------------------------> as from DISABLED, at once
//   ERROR ----OFF-------------------------> DISABLED   retries stop; OFF answered OK
//   ENABLED --OFF-------------------------> DISABLED   off() runs; OFF answered OK
//   ENABLED --loop() or command() fails---> ERROR      off() runs; listeners get ERROR
//   any ------shutdown--------------------> off() if ENABLED, then cleanup()
//   init() throws: the component stays in ERROR for good; ON is answered ERROR.
//
// The lifecycle contract: what a hook may rely on (and what it must not redo).
//
//  1. Threads. The constructor, init() and cleanup() run in the executor's main
//     thread (not RT: allocate, open files, throw on failure). on(), off(),
//     command() and check_parameters() run in the command task; loop() runs in the
//     data task (DataComponentBase). The command task never runs on()/off() while
//     loop() runs: loop() is gated off before off() and only gated on after on()
//     returned kOk, so the two tasks never touch the component's state at once
//     across ON and OFF. command() may run while loop() runs: share state through a
//     Handoff (rack/core/handoff.h) or atomics. A job that loop() posts to a compute
//     worker (add_compute_worker) runs in the worker's thread until loop()'s wait()
//     returns; an I/O worker's body (add_io_worker) runs beside every hook.
//  2. Order. init() once, before anything else; then any number of on()/off()
//     rounds; cleanup() once at shutdown (after off() if the component was ENABLED).
//     init() throwing: the component stays in ERROR for good, on() never runs.
//  3. off() runs after every on() that was called, whether it returned kOk, kError
//     or threw: a failed on() is undone by off() at once (so off() must cope with an
//     on() that stopped halfway), and an ENABLED component's off() runs when it
//     leaves ENABLED (OFF, loop()/command() failure, shutdown). off() also runs when
//     ON failed in the framework's own step before on() (a declared input's source
//     did not switch on or refused the subscription).
//  4. What the framework does by itself, so that hooks must not: for every declared
//     input (DataComponentBase::declare_input) it switches the source on (cascading
//     ON) and subscribes BEFORE on(), and unsubscribes AFTER off(); every other
//     subscription still active after off() (subscribe() by hand) is stopped too. It
//     drops every listener with an ERROR when the component leaves ENABLED, drains
//     stale input while the component is not ENABLED, renews subscription leases,
//     retries on() every retry_ms in ERROR (re-subscribing), detects a declared
//     input's silence (the parameter silence_ms) and a producer's ERROR, and passes
//     END_OF_STREAM on.
//  5. Failure. on()/loop()/command() say why with set_error_reason() before returning
//     kError; an exception counts as kError. One component's failure affects that
//     component only.
//  6. Parameters are filled and checked (check_parameters) before init(); SET_PARAM
//     may change a value at any time unless its Spec says init_only.
//
// A data component's listeners get an ERROR message and are dropped whenever it
// leaves ENABLED. An exception or error in one component affects that component only.
//
// Real-time contract: on(), off(), command() and everything they call run in the
// command task (an RT task): they must not allocate, lock without PI, print or make
// blocking system calls. init() and cleanup() are not RT: allocate there. The
// helpers below are RT-safe unless they say otherwise.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rack/core/compute_worker.h"
#include "rack/core/gdos.h"
#include "rack/core/parameters.h"
#include "rack/core/wire.h"
#include "rack/core/wire_tasks.h"
#include "rack/rt/clock.h"
#include "rack/rt/modeswitch.h"
#include "rack/rt/page_faults.h"
#include "rack/rt/pi_mutex.h"
#include "rack/rt/task_sched.h"
#include "rack/tims/endpoint.h"

namespace rack {

enum class ComponentState : uint8_t { kDisabled = 0, kEnabled = 1, kError = 2 };
[[nodiscard]] const char* describe(ComponentState s) noexcept;

enum class HookResult : uint8_t { kOk, kError };
enum class CommandResult : uint8_t { kHandled, kUnknown };
enum class DataTaskMode : uint8_t { kNone = 0, kPeriodic = 1, kTriggered = 2 };
[[nodiscard]] const char* describe(DataTaskMode m) noexcept;

struct TaskSettings {
  int priority = 0;  // 1..99 SCHED_FIFO, 0 normal
  int cpu = -1;      // -1: any
  std::size_t stack_bytes = 256 * 1024;
  // Mode-switch detection for this task (off, warn, abort); unset: the host file's
  // modeswitch.mode, or off for a priority-0 task (normal scheduling is not real-time:
  // MCL and other heavy components allocate there by design).
  std::optional<rt::modeswitch::Mode> modeswitch;
};

// How the executor runs one component (from the host file).
struct ComponentSettings {
  std::string name;       // the host file's name ("ladar_front")
  std::string impl;       // implementation class ("Generator")
  tims::Address address;  // command mailbox: Class(sys/inst)
  TaskSettings command_task{30, -1, 256 * 1024, std::nullopt};
  TaskSettings data_task{40, -1, 256 * 1024, std::nullopt};
  int64_t period_ns = 0;  // periodic data task
  // Periodic data task: deadlines at whole multiples of period_ns on CLOCK_MONOTONIC
  // plus this (data_task.phase_ms, 0 <= phase < period); -1: one period after start.
  int64_t phase_ns = -1;
  int64_t data_timeout_ns = rt::kNsPerSec;  // triggered: loop() runs after this long without input
  int64_t retry_ns = rt::kNsPerSec;         // ERROR back-off
  int64_t rpc_timeout_ns = rt::kNsPerSec;   // cascading ON and other calls from hooks
  uint32_t rpc_retries = 0;                 // more attempts after a timeout (tims::RetryPolicy)
  uint32_t ring_size = 64;
  uint32_t command_slots = 16;
  uint32_t input_slots = 32;
  uint32_t max_listeners = 16;
  // A listener (GET_CONT_DATA) that does not renew within this long is dropped with an
  // ERROR (DataComponentBase: leases). Consumers renew every lease / 4.
  int64_t lease_ns = 10 * rt::kNsPerSec;
  bool autostart = false;
  // The host file's folder (absolute; "" outside a host file): relative paths in
  // parameters and commands (STORE_DATA) are taken from it (rack/core/parameters.h).
  std::string base_dir;
};

class Executor;
struct HostLoader;

class Component {
 public:
  virtual ~Component();
  Component(const Component&) = delete;
  Component& operator=(const Component&) = delete;

  [[nodiscard]] const ComponentSettings& settings() const noexcept { return settings_; }
  [[nodiscard]] const std::string& name() const noexcept { return settings_.name; }
  [[nodiscard]] tims::Address address() const noexcept { return settings_.address; }
  [[nodiscard]] ComponentState state() const noexcept { return state_.load(std::memory_order_acquire); }
  [[nodiscard]] ParameterSet& parameters() noexcept { return params_; }
  [[nodiscard]] const ParameterSet& parameters() const noexcept { return params_; }
  [[nodiscard]] virtual DataTaskMode data_task_mode() const noexcept { return DataTaskMode::kNone; }
  // Statistics for GET_STATS and rackd's status lines. Any thread, RT-safe.
  virtual void fill_stats(wire::StatsReply& out) const noexcept;
  // The data task's wake-up latency histogram for GET_LATENCY (wire::LatencyHistogram:
  // the fixed edges, counts all 0 without a data task). Any thread, RT-safe: no
  // allocation, O(rt::LatencyStats::kBuckets).
  virtual void fill_latency(wire::LatencyHistogram& out) const noexcept;
  // Who subscribes to this component now (GET_LISTENERS, wire::ListenersReply): a data
  // component's continuous listeners, none for a component without a data task. Any
  // thread, RT-safe: no allocation; a data component reads its listener table under
  // its priority-inheritance mutex (rt::PiMutex), O(max_listeners).
  virtual void fill_listeners(wire::ListenersReply& out) const noexcept;
  // How its tasks run (GET_TASKS, wire::TasksReply): per task the host file's priority
  // and CPU, the kernel's policy, priority and CPUs as of the last sample_tasks(), the
  // data task's period and measured interval; and its host's TiMS networks (set by the
  // executor before the tasks start; none without an executor). Any thread, RT-safe:
  // no allocation, atomic loads.
  virtual void fill_tasks(wire::TasksReply& out) const noexcept;
  // Reads how its tasks run from the kernel (rack/rt/task_sched.h) and, for a data
  // component, the mean interval of its loop() runs since the last call. Not RT-safe:
  // one non-RT thread (the executor's GDOS thread once a second).
  virtual void sample_tasks() noexcept;
  // Class-specific progress for rackd's --status lines ("" for none): appended to
  // `out` as one short line. Called from rackd's main thread while the tasks run, so
  // it reads only atomics or other thread-safe state. Not RT-safe (it may allocate).
  virtual void describe_status(std::string& out) const { (void)out; }
  // Page faults of the command task and the data task since the end of their
  // start-up (rack/rt/page_faults.h). sample_faults() reads them from /proc: not
  // RT-safe, a non-RT thread (the executor's GDOS thread does it once a second, rackd's
  // status lines before printing). The accessors' last() is RT-safe (fill_stats uses it).
  void sample_faults() const noexcept;
  [[nodiscard]] const rt::TaskFaults& command_task_faults() const noexcept { return command_faults_; }
  [[nodiscard]] const rt::TaskFaults& data_task_faults() const noexcept { return data_faults_; }
  // This component as a GDOS log source (address, name, level). Any thread.
  [[nodiscard]] const gdos::LogSource& log_source() const noexcept { return log_source_; }
  // The standard parameter that holds the log level (every component has it).
  static constexpr const char* kLogLevelParam = "gdosLevel";

 protected:
  Component();  // declares the standard parameter gdosLevel

  // ---- logging (GDOS, rack/core/gdos.h) ----
  // printf-style, checked at compile time, tagged with this component's address.
  // RT-safe from the command and data tasks (no formatting, allocation, lock or
  // system call: the arguments are copied into the task's log ring; a full ring
  // drops and counts). From init()/cleanup() (main thread) the text is formatted
  // at once (not RT). A TiMS address argument for %s prints as `Ladar(0/1)`.
  // Levels: print (always), error, warning, info, detail; the threshold is the
  // parameter gdosLevel (host file, or `rackctl set-param NAME gdosLevel warning`).
  template <class... Args>
  void log_print(gdos::Format<Args...> f, const Args&... a) const noexcept {
    gdos::log(log_source_, gdos::Level::kPrint, f, a...);
  }
  template <class... Args>
  void log_error(gdos::Format<Args...> f, const Args&... a) const noexcept {
    gdos::log(log_source_, gdos::Level::kError, f, a...);
  }
  template <class... Args>
  void log_warning(gdos::Format<Args...> f, const Args&... a) const noexcept {
    gdos::log(log_source_, gdos::Level::kWarning, f, a...);
  }
  template <class... Args>
  void log_info(gdos::Format<Args...> f, const Args&... a) const noexcept {
    gdos::log(log_source_, gdos::Level::kInfo, f, a...);
  }
  template <class... Args>
  void log_detail(gdos::Format<Args...> f, const Args&... a) const noexcept {
    gdos::log(log_source_, gdos::Level::kDetail, f, a...);
  }

  // ---- hooks ----
  virtual void init() {}                               // non-RT: allocate; throw on failure
  virtual HookResult on() { return HookResult::kOk; }  // switch the device/algorithm on
  virtual void off() {}                                // bounded time; never blocks long
  // Class-specific requests (type >= 21). Reply with reply()/reply_error().
  virtual CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) {
    (void)request;
    (void)body;
    return CommandResult::kUnknown;
  }
  virtual void cleanup() {}  // non-RT
  // The class's rules for its parameter values, in one place: what init() relies on
  // and SET_PARAM must keep (a mode of a fixed set, "x,y" text, min below max, ...).
  // Called by the host file loader once the file's values are in (a refusal is an
  // error at that parameter's line: rackd --check reports it, exit 2), before init(),
  // and by SET_PARAM with the candidate value in `values` (a refusal answers ERROR
  // with the reason and keeps the old value). Single parameters' ranges and choices
  // belong in their Parameter::Spec; this is for what a Spec cannot say. Return false
  // and fill `problem`. RT-safe (runs in the command task): no allocation, no file or
  // device access; read the values through `values` only.
  [[nodiscard]] virtual bool check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept {
    (void)values;
    (void)problem;
    return true;
  }

  // ---- declaration (constructor only) ----
  Parameter& declare_int(const std::string& n, int64_t v, Parameter::Spec s = {}) {
    return params_.declare_int(n, v, std::move(s));
  }
  Parameter& declare_float(const std::string& n, double v, Parameter::Spec s = {}) {
    return params_.declare_float(n, v, std::move(s));
  }
  Parameter& declare_bool(const std::string& n, bool v, Parameter::Spec s = {}) {
    return params_.declare_bool(n, v, std::move(s));
  }
  Parameter& declare_string(const std::string& n, const std::string& v, Parameter::Spec s = {}) {
    return params_.declare_string(n, v, std::move(s));
  }
  // A required string parameter naming another component (host-file name or
  // `Class(sys/inst)`); the executor resolves it and orders start and shutdown by it.
  Parameter& declare_component_ref(const std::string& n, const std::string& doc);
  // Command mailbox slot size, if the class's commands carry large bodies.
  void set_command_slot_size(uint32_t bytes) { command_slot_size_ = bytes; }

  // ---- I/O workers (init() only) ----
  // Components never make threads (STYLE.md 3). Blocking device I/O (a TCP link, a
  // camera's capture) runs in an I/O worker: the executor runs `body` in a non-RT
  // thread of its own (SCHED_OTHER, on the housekeeping CPUs, rackd's thread listing
  // names it "I/O worker"), with a log ring of its own, from after a successful
  // init() until shutdown: then, after the tasks have ended, it calls `stop` (which
  // must make `body` return soon; any thread) and joins the thread before cleanup().
  // `name` is the thread's name (cut to 15 characters). Not RT-safe.
  void add_io_worker(const std::string& name, std::function<void()> body, std::function<void()> stop);

  // ---- compute workers (init() only) ----
  // A second thread for the data task's bulk computation (MCL's scan likelihood),
  // owned by the executor (rack/core/compute_worker.h: the data task posts one job at a
  // time and waits for it). It serves the data task, which waits for it, so it runs
  // where the data task may run and as urgently: the executor gives it the data task's
  // priority (0: normal scheduling) and CPUs (its `cpu:`, or else the partition's RT
  // CPUs for an RT task and the housekeeping CPUs for a non-RT one; a data task pinned
  // to one CPU shares it with its worker, which then brings no parallelism: rackd says
  // so). It starts after a successful init(), before the tasks, with a log ring of its
  // own, and is stopped and joined after the tasks ended, before cleanup(). The
  // thread's name is the component's name (cut to 10 characters), ':' and `name` (cut
  // to 15 in all); rackd's thread listing shows it as a compute worker. Without an
  // executor, or in a stepped one (stepper.h), no thread serves it: a job runs on the
  // poster's thread. The worker lives as long as the component. Not RT-safe.
  ComputeWorker& add_compute_worker(const std::string& name);

  // ---- for hooks (RT-safe) ----
  // The address a component-ref parameter resolved to.
  [[nodiscard]] tims::Address resolved(const Parameter& ref) const noexcept;
  // RPCs from on() and command() (the command task's own reply mailbox).
  [[nodiscard]] tims::Endpoint& command_endpoint() noexcept { return *command_endpoint_; }
  // Cascading ON: switch on a component this one depends on, and wait for its answer.
  // On failure the error reason names `dest` and carries its answer's reason.
  [[nodiscard]] HookResult switch_on(tims::Address dest) noexcept;
  // Why this component fails, for the ERROR it is about to enter: on(), command() or
  // loop() call it before returning kError, naming the cause (the producer that went
  // OFF, the file that failed). The ERROR's GDOS line and the answer to ON carry it
  // ("on() failed" alone when no reason was given). The last reason before a failure
  // wins. RT-safe from the command and data tasks (copies under a PI mutex).
  void set_error_reason(const char* reason) noexcept;
  void reply(const tims::MessageHeader& request, int8_t type, std::span<const tims::ConstBuffer> body = {}) noexcept;
  template <tims::Payload T>
  void reply_with(const tims::MessageHeader& request, int8_t type, const T& body) noexcept {
    const tims::ConstBuffer part = tims::buffer_of(body);
    reply(request, type, std::span<const tims::ConstBuffer>(&part, 1));
  }
  void reply_error(const tims::MessageHeader& request, const char* reason) noexcept;
  // Counts a malformed request and answers it ERROR with `reason`.
  void reject_malformed(const tims::MessageHeader& request, const char* reason) noexcept;
  // Declares a file descriptor a real-time device (CAN socket, serial port): the
  // mode-switch detector then allows read/write/ioctl/poll/send/recv on it inside
  // cycles. Call from init() or on(); unregister before closing it. RT-safe.
  static void register_rt_device(int fd) noexcept { (void)rt::modeswitch::register_rt_device(fd); }
  static void unregister_rt_device(int fd) noexcept { rt::modeswitch::unregister_rt_device(fd); }
  [[nodiscard]] tims::Router& router() noexcept { return *router_; }

 private:
  friend class Executor;
  friend class Stepper;
  friend struct SteppedTask;
  friend struct HostLoader;
  friend class DataComponentBase;

  // Framework internals (called by the executor).
  virtual void attach(tims::Router& router);  // settings_ already set by the loader
  void detach() noexcept;
  bool run_init(std::string& error);  // non-RT; catches
  void run_command_task() noexcept;   // the command task's body: command_pass() per wake-up
  // One pass of the command task, the thread's and a stepped executor's: a failed
  // loop() (to ERROR), the message `r` if one came (kOk: in command_buffer_), then the
  // retry of on() in ERROR when its back-off has passed. Command task (RT-safe).
  void command_pass(const tims::Mailbox::Received& r) noexcept;
  // How long the command task may wait for a message: until the next retry in ERROR,
  // for ever otherwise. RT-safe.
  [[nodiscard]] int64_t command_wait_ns() const noexcept;
  // Stepped executors (rack/core/stepper.h): command_pass() for every queued message
  // without waiting (at least one pass, for a due retry). true: a message was handled.
  bool step_commands() noexcept;
  void request_stop() noexcept;  // wakes every task of this component
  void run_cleanup() noexcept;   // non-RT; catches

  // Extension points for DataComponentBase.
  virtual bool handle_data_request(const tims::MessageHeader&, std::span<const std::byte>) noexcept { return false; }
  virtual void leaving_enabled() noexcept {}  // before off(): stop the data task's loop
  virtual void entered_enabled() noexcept {}  // after on() succeeded
  virtual void stop_data_task() noexcept {}
  // Around on() and off() (contract rules 3 and 4): before_on() runs before on() (a
  // failure skips on() but not off()), after_off() after every off(). Command task.
  virtual HookResult before_on() noexcept { return HookResult::kOk; }
  virtual void after_off() noexcept {}

  void handle(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept;
  void handle_on(const tims::MessageHeader* request) noexcept;
  void handle_off() noexcept;
  void go_error() noexcept;  // ENABLED -> ERROR (loop or command failure)
  HookResult call_on() noexcept;
  void call_off() noexcept;
  void handle_get_param(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept;
  void handle_set_param(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept;
  void handle_get_class(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept;

 protected:
  // For DataComponentBase: the data task reports a failed loop().
  void report_loop_failure() noexcept;
  [[nodiscard]] bool stopping() const noexcept { return stop_.load(std::memory_order_acquire); }
  void set_state(ComponentState s) noexcept;

 private:
  void sync_log_level() noexcept;  // gdosLevel parameter -> log_source_ (RT-safe)
  // Moves the pending error reason into `out` ("" when none) and clears it.
  void take_error_reason(char (&out)[96]) noexcept;
  void show_reason(const char* reason) noexcept;  // the present ERROR's reason ("" on leaving it)

  ComponentSettings settings_;
  ParameterSet params_;
  gdos::LogSource log_source_;
  Parameter* log_level_param_ = nullptr;
  std::vector<std::pair<const Parameter*, tims::Address>> refs_;  // filled by the executor
  struct IoWorker {
    std::string name;
    std::function<void()> body, stop;
  };
  std::vector<IoWorker> io_workers_;  // add_io_worker() in init(); the executor runs them
  struct ComputeWorkerDecl {
    std::string name;
    std::unique_ptr<ComputeWorker> worker;
  };
  std::vector<ComputeWorkerDecl> compute_workers_;  // add_compute_worker() in init(); the executor serves them
  uint32_t command_slot_size_ = 1024;
  tims::Router* router_ = nullptr;
  std::unique_ptr<tims::Mailbox> command_mailbox_;
  std::unique_ptr<tims::Mailbox> command_reply_mailbox_;
  std::unique_ptr<tims::Endpoint> command_endpoint_;
  std::vector<std::byte> command_buffer_;
  std::vector<wire::ParamRecord> param_records_;
  // Its class's description (rack/core/class_description.h), encoded by the host
  // loader before the tasks start; GET_CLASS serves pages of it (empty: ERROR).
  std::vector<std::byte> class_description_;
  std::size_t class_description_base_ = 0;  // its length without the optional sections
  // State: written by the command task, read by everyone (acquire/release so a
  // reader that sees ENABLED also sees what on() wrote).
  std::atomic<ComponentState> state_{ComponentState::kDisabled};
  std::atomic<bool> stop_{false};
  // Set by the data task when loop() failed; consumed by the command task.
  std::atomic<bool> loop_failed_{false};
  mutable rt::PiMutex reason_mutex_;  // guards error_reason_, shown_reason_ (command and data task, GET_STATS)
  char error_reason_[96] = {};
  char shown_reason_[96] = {};  // the reason of the present ERROR (GET_STATS); "" otherwise
  bool init_failed_ = false;
  char init_error_[120] = {};
  int64_t retry_at_ns_ = 0;
  // Statistics (written by the command task, relaxed: counters).
  std::atomic<uint64_t> commands_{0}, malformed_{0}, errors_{0};
  // Marked by each task at the end of its start-up (the executor's task bodies);
  // mutable: sampling from a const status path updates the figures only.
  mutable rt::TaskFaults command_faults_, data_faults_;
  // How the tasks run, as the kernel says (sample_tasks(), GET_TASKS).
  rt::TaskSched command_sched_, data_sched_;
  // Its host's networks for GET_TASKS (the network_* fields only): written by the
  // executor before the tasks start, read-only afterwards.
  wire::TasksReply host_networks_{};
  // The kernel's reading of one task into record `i` of `out` (measured 0 when there
  // is none yet; DataComponentBase::fill_tasks uses it for the data task). RT-safe.
  void fill_task_record(wire::TasksReply& out, std::size_t i, const rt::TaskSched& sched) const noexcept;
};

}  // namespace rack
