// A stepping executor with a virtual clock (Orocos RTT's SlaveActivity, ros2_control's
// test harness): a test drives components deterministically, with no task threads,
// no sleeps and no polling.
//
// An executor made with ExecutorOptions::stepped starts no task threads. Instead:
//  - commands are served synchronously: a message the router delivers into a
//    component's command mailbox runs that component's command task body (one pass
//    per message, Component::command_pass) in the sender's thread before send()
//    returns, so a request from the test, a cascading ON or a subscription from
//    on() is answered before its caller waits for the reply;
//  - the data tasks run when the Stepper steps them: the same loop body the thread
//    runs (DataComponentBase::periodic_cycle / triggered_plan + triggered_after),
//    without the wait: a periodic task runs one cycle when its deadline has come, a
//    triggered one when a sample waits in its input mailbox or its timeout has passed;
//  - time is an rt::VirtualClock that the test installs before start() and moves
//    (directly, or through run_for()): every rt::monotonic_ns() and rt::host_time_ns()
//    of the executor and the components reads it, so periods, watchdogs, silence
//    limits, leases and the back-off in ERROR follow it.
//
//   rt::VirtualClock clock;                                  // before the executor starts
//   ExecutorOptions options;
//   options.stepped = true;
//   Executor executor(std::move(host), std::move(options));  // a host file with lcm: false
//   executor.start();
//   Stepper stepper(executor);
//   ... a request to a component is answered at once (Endpoint::call) ...
//   stepper.run_for(100 * rt::kNsPerMs);       // 10 cycles of a 10 ms task, and what they trigger
//   stepper.step("odometry");                  // or one pass of one data task, now
//
// tests/unit/test_support.h: HostUnderTest(yaml, {}, false, Stepping::kStepped) does
// the above and offers stepper(). README "Testing components: the stepping executor".
//
// Compute workers (Component::add_compute_worker, MCL's likelihood) get no thread:
// a job the data task posts runs inside that step, on the stepping thread, when the
// data task waits for it (ComputeWorker::wait() runs it through the same call a
// serving thread makes), so the step returns with the job done.
//
// What differs from the threads: a command for a component whose data task is in
// loop() at that moment (a loop() that calls its own component) waits until loop()
// returns, so such a call times out (real time: rpc_timeout). A host with LCM is
// refused (start() throws: use `lcm: false`). A compute worker's job runs after the
// poster's own share of the work instead of beside it (the same result, not in
// parallel); rackd's thread listing has no compute worker to show.
//
// Real-time contract: test code, not RT-safe (and single-threaded: one thread steps,
// sends and moves the clock). The passes it runs are the tasks' RT code.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "rack/core/data_component.h"
#include "rack/rt/clock.h"
#include "rack/tims/mailbox.h"

namespace rack {

class Executor;

// One component of a stepped executor: its command mailbox's delivery hook (the
// command task's pass in the sender's thread). Owned by the executor.
struct SteppedTask final : tims::DeliveryHook {
  SteppedTask(Component& c, DataComponentBase* d) noexcept : component(c), data(d) {}
  ~SteppedTask() override;
  SteppedTask(const SteppedTask&) = delete;
  SteppedTask& operator=(const SteppedTask&) = delete;
  void delivered(tims::Mailbox& mailbox) noexcept override;

  Component& component;
  DataComponentBase* data;  // nullptr: no data task
  // A pass of this component runs (its command task's, or its data task's): a
  // command sent to it from inside waits in its mailbox for the pass after.
  bool busy = false;
  bool hooked = false;  // the hook is set on the command mailbox
};

class Stepper {
 public:
  // `executor` was made with ExecutorOptions::stepped and has been started (throws
  // std::logic_error otherwise, or when no rt::VirtualClock is installed).
  explicit Stepper(Executor& executor);

  [[nodiscard]] rt::VirtualClock& clock() const noexcept { return *clock_; }
  [[nodiscard]] int64_t now_ns() const noexcept { return clock_->now_ns(); }
  // Moves the clock only; nothing runs (run_for runs what falls due on the way).
  void advance(int64_t ns) noexcept { (void)clock_->advance(ns); }

  // One pass of the data task of `component` (a name or address as Executor::find
  // takes) at the present time, then its command task's (a failed loop() puts it in
  // ERROR at once, as the thread would). true: loop() ran. Throws std::invalid_argument
  // for an unknown component or one without a data task.
  bool step(const std::string& component);
  bool step(Component& component);
  // A pass of every command task: the retries in ERROR whose back-off has passed, a
  // loop() failure not handled yet. (Requests need none: they are served when sent.)
  void step_commands();

  // Runs the executor for `duration_ns` of virtual time as its threads would: moves
  // the clock to the earliest moment a task has something to do (a periodic
  // deadline, a triggered task's timeout or a lease renewal, a retry in ERROR; a
  // sample waiting is now), steps every task due then in host-file order (so a
  // sample published in a cycle reaches its consumers at the same virtual time),
  // and so on; ends with the clock at now + duration_ns. Returns the data-task cycles
  // run (a periodic task's count while it is off too, as its thread's do).
  uint64_t run_for(int64_t duration_ns);
  uint64_t run_until(int64_t t_ns);
  // As run_for, but checks `done` after every instant that ran something and stops
  // there when it holds: true then (the clock stays at that instant), false when
  // `limit_ns` passed first.
  bool run_until(const std::function<bool()>& done, int64_t limit_ns);

 private:
  SteppedTask& task_of(Component& component);
  bool step_task(SteppedTask& t);
  // Every task due at the present time, until none is (bounded). Cycles run.
  uint64_t run_due();
  [[nodiscard]] int64_t next_due_ns() const noexcept;

  Executor& executor_;
  rt::VirtualClock* clock_;
};

}  // namespace rack
