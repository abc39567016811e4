// How a task runs, as the kernel sees it: its scheduling policy and priority, the
// CPUs it may run on and the one it ran on last (issue 25: `rackctl alloc --live`
// shows what runs, not what a host file asked for; a task that fell back to normal
// scheduling, or a thread someone moved with chrt or taskset, shows as it is).
//
// A non-RT thread reads them (read_thread_sched: /proc/self/task/TID/stat fields 39
// processor, 40 rt_priority, 41 policy; sched_getaffinity) and keeps the last reading
// (TaskSched::sample, the executor's GDOS thread once a second, as the page faults of
// rack/rt/page_faults.h); anyone takes it with last(). A sequence lock keeps policy,
// priority and CPUs of one reading together.
//
// Real-time contract: read_thread_sched() and sample() are not RT-safe (system calls):
// a non-RT thread, one at a time per TaskSched. last() is RT-safe (atomic loads, at
// most kTries attempts, no waiting), any thread.
#pragma once

#include <sys/types.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace rack::rt {

struct SchedInfo {
  static constexpr std::size_t kCpuWords = 4;  // CPUs 0..255
  bool measured = false;                       // false: not read yet, or the thread is gone
  int policy = -1;    // the kernel's number: SCHED_OTHER 0, FIFO 1, RR 2, BATCH 3, IDLE 5, DEADLINE 6
  int priority = 0;   // rt_priority: 1..99 under SCHED_FIFO/SCHED_RR, else 0
  int last_cpu = -1;  // the CPU it ran on last
  std::array<uint64_t, kCpuWords> affinity{};  // bit c % 64 of word c / 64: may run on CPU c
  int online_cpus = 0;                         // CPUs online at the reading
  int64_t time_ns = 0;                         // CLOCK_MONOTONIC of the reading
};

// Thread `tid` of this process now. measured is false when its stat file cannot be
// read or parsed, or its affinity cannot be asked. Not RT-safe; allocates nothing.
[[nodiscard]] SchedInfo read_thread_sched(pid_t tid) noexcept;

class TaskSched {
 public:
  static constexpr int kTries = 4;
  // Non-RT thread: reads thread `tid` (0: nothing, a task that has not started) and
  // keeps the reading for last(). A failed reading keeps the previous one.
  void sample(pid_t tid) noexcept;
  // The last reading (measured false before the first, or when a reader met a
  // writer kTries times in a row). RT-safe.
  [[nodiscard]] SchedInfo last() const noexcept;

 private:
  // Sequence lock: odd while sample() writes. The writer's release store of the even
  // value publishes the fields; a reader's acquire load and fence pair with it.
  std::atomic<uint32_t> seq_{0};
  std::atomic<bool> measured_{false};
  std::atomic<int> policy_{-1}, priority_{0}, last_cpu_{-1}, online_cpus_{0};
  std::array<std::atomic<uint64_t>, SchedInfo::kCpuWords> affinity_{};
  std::atomic<int64_t> time_ns_{0};
};

}  // namespace rack::rt
