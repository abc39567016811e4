// A compute worker: a second thread for one component's bulk computation (MCL's scan
// likelihood), owned by the executor. Components never make threads (STYLE.md 3): a
// component declares a worker in init() (Component::add_compute_worker) and hands it
// one job at a time from its data task; the executor runs the thread that serves it,
// with the data task's priority and CPUs (rack/core/component.h says why), names it,
// gives it a GDOS ring, and stops and joins it after the tasks ended, before cleanup().
//
// One job at a time, from one thread (the poster, normally the data task):
//
//   auto half = [&] { weigh(m / 2, m); };
//   worker.post(half);      // returns at once; the worker runs half()
//   weigh(0, m / 2);        // meanwhile, on the poster's thread
//   if (!worker.wait()) ... // half() has returned (false: it threw)
//
// The job is referenced, not copied: it must live until wait() returns. When no thread
// serves the worker (code outside an executor, a stepped executor: rack/core/stepper.h,
// a worker not started yet or already stopped), wait() runs the job on the poster's
// thread: the result is the same, only not in parallel. Nothing here ever waits for a
// thread that is not there.
//
// Real-time contract: post() and wait() are RT-safe (no allocation; a priority-
// inheritance mutex and a futex condition variable, rack/rt/pi_mutex.h); wait()
// blocks for as long as the job runs. serve() and stop() belong to the thread that
// serves the worker and its owner (the executor; benchmarks and tests outside one).
// Thread-safety: post()/wait() from one poster thread; serve() from one thread;
// stop() and serving() from any thread.
#pragma once

#include <cstdint>

#include "rack/rt/pi_mutex.h"

namespace rack {

class ComputeWorker {
 public:
  ComputeWorker() = default;
  ComputeWorker(const ComputeWorker&) = delete;
  ComputeWorker& operator=(const ComputeWorker&) = delete;

  // Hands `job` (a callable without arguments) to the worker; call wait() before the
  // next post() and before `job` goes out of scope. RT-safe.
  template <class F>
  void post(F& job) noexcept {
    post_raw([](void* f) { (*static_cast<F*>(f))(); }, &job);
  }
  // The same with a plain function and its argument. RT-safe.
  void post_raw(void (*fn)(void*), void* arg) noexcept;
  // Returns when the posted job has returned: true, or false when it threw (the
  // exception is not passed on). Runs the job here when no thread serves the worker.
  // True at once when nothing was posted. RT-safe (blocks while the job runs).
  [[nodiscard]] bool wait() noexcept;
  // A thread serves the worker now (between the start and the end of serve()).
  [[nodiscard]] bool serving() const noexcept;

  // The serving thread's body: runs the posted jobs until stop(); a job posted before
  // stop() still runs. Once only. Not for components (the executor calls it).
  void serve() noexcept;
  // Makes serve() return after the job it runs, if any. Any thread; idempotent.
  void stop() noexcept;
  // Jobs run by the serving thread, and on the poster's thread (no thread served).
  // Any thread (read under the worker's mutex).
  [[nodiscard]] uint64_t jobs_served() const noexcept;
  [[nodiscard]] uint64_t jobs_inline() const noexcept;

 private:
  static bool run(void (*fn)(void*), void* arg) noexcept;  // false: the job threw

  mutable rt::PiMutex mutex_;  // guards everything below
  rt::PiCondVar cv_;           // a job posted or finished; stop()
  void (*fn_)(void*) = nullptr;
  void* arg_ = nullptr;
  bool posted_ = false;   // a job waits for the serving thread
  bool running_ = false;  // the serving thread runs a job
  bool inline_ = false;   // a job waits for wait() to run it (no thread served at post())
  bool failed_ = false;   // the last job threw
  bool serving_ = false;
  bool stop_ = false;
  uint64_t served_ = 0, inlined_ = 0;
};

}  // namespace rack
