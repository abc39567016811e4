// Page faults of one task after its start-up: the evidence for "an RT task does not
// fault once it runs" (memory locked before the threads start, stacks pre-faulted,
// nothing allocated or first touched in the cycle).
//
// The task marks the end of its own start-up (mark_started(): its thread id and the
// thread's fault counters at that moment, from getrusage(RUSAGE_THREAD)). A non-RT
// thread (the executor's GDOS thread once a second, rackd's status lines) reads the
// thread's counters from /proc/self/task/TID/stat (sample()), so the task itself
// makes no system call for it; anyone reads the last sample (last()).
//
// Real-time contract: mark_started() and sample() are not RT-safe (system calls);
// mark_started() belongs to the task's start-up, sample() to a non-RT thread.
// last() and started() are RT-safe (atomic loads), any thread.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <cstdint>

namespace rack::rt {

struct FaultCount {
  uint64_t minor = 0;     // page faults served without I/O (first touch, copy-on-write)
  uint64_t major = 0;     // page faults that needed I/O
  bool measured = false;  // false: the task has not marked its start-up yet, or /proc unreadable
};

// The fault counters of thread `tid` of this process, from /proc/self/task/TID/stat
// (fields 10 and 12). measured is false when the file cannot be read. Not RT-safe.
[[nodiscard]] FaultCount read_thread_faults(pid_t tid) noexcept;

class TaskFaults {
 public:
  // Called by the task itself at the end of its start-up. Not RT-safe (gettid,
  // getrusage): call it once, before the first cycle.
  void mark_started() noexcept;
  // Non-RT thread: reads the task's counters now and keeps the difference to the
  // start-up mark for last(). Returns it (measured false before mark_started()).
  FaultCount sample() noexcept;
  // The faults since start-up as of the last sample(). RT-safe.
  [[nodiscard]] FaultCount last() const noexcept;
  [[nodiscard]] bool started() const noexcept { return tid_.load(std::memory_order_acquire) != 0; }
  // The task's thread id once it marked its start-up, else 0. RT-safe.
  [[nodiscard]] pid_t tid() const noexcept { return tid_.load(std::memory_order_acquire); }

 private:
  std::atomic<pid_t> tid_{0};
  std::atomic<uint64_t> base_minor_{0}, base_major_{0};
  std::atomic<uint64_t> minor_{0}, major_{0};
  std::atomic<bool> sampled_{false};
};

}  // namespace rack::rt
