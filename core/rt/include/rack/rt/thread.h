// Real-time threads: SCHED_FIFO priority, CPU affinity and stack size, set before the
// thread runs (explicit scheduling attributes), so a task never runs a cycle with the
// wrong policy. Components never make threads; the executor does (STYLE.md 3).
//
// Real-time contract: nothing here is RT-safe; start() and join() are set-up calls.
// Thread-safety: one Thread object is used by one owner thread.
#pragma once

#include <pthread.h>
#include <sys/types.h>

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace rack::rt {

struct ThreadConfig {
  std::string name;                      // shown in top/ps; cut to 15 characters
  int priority = 0;                      // 1..99: SCHED_FIFO; 0: SCHED_OTHER
  int cpu = -1;                          // pin to this CPU; -1: any (or `cpus`)
  std::size_t stack_bytes = 256 * 1024;  // pre-faulted at start
  std::vector<int> cpus{};               // with cpu -1: run on these CPUs; empty: any
};

enum class ThreadStart {
  kRealTime,  // running with the requested SCHED_FIFO priority
  kFallback,  // RT refused (EPERM) and fallback allowed: running SCHED_OTHER
  kNormal,    // priority 0 was asked for
};

class Thread {
 public:
  Thread() = default;
  ~Thread();
  Thread(const Thread&) = delete;
  Thread& operator=(const Thread&) = delete;

  // Starts `body` on a new thread. Throws std::system_error when the thread cannot
  // be created (or when RT is refused and `allow_fallback` is false), naming the
  // thread and errno. Not RT-safe.
  ThreadStart start(const ThreadConfig& config, std::function<void()> body, bool allow_fallback);

  void join();  // Not RT-safe.
  [[nodiscard]] bool joinable() const noexcept { return started_; }

 private:
  pthread_t handle_{};
  bool started_ = false;
  ThreadConfig config_;
  std::function<void()> body_;
  static void* trampoline(void* self);
};

// Sets the CPU affinity of thread `tid` of this process (0: the calling thread) to
// `cpus`. Returns errno or 0 (EINVAL for an empty list). Not RT-safe.
int set_thread_affinity(pid_t tid, const std::vector<int>& cpus) noexcept;

// "0-1,3" (the kernel's cpulist format) from CPU numbers (sorted, duplicates
// dropped). Not RT-safe.
[[nodiscard]] std::string cpu_list_string(std::vector<int> cpus);

// Gives the calling thread SCHED_FIFO `priority` (0: SCHED_OTHER). Returns errno or 0.
int set_current_thread_priority(int priority) noexcept;

// The number of threads of this process (/proc/self/stat, field 20: one open and read),
// or -1 when it cannot be read. Not RT-safe (system calls); allocates nothing.
[[nodiscard]] long process_thread_count() noexcept;

}  // namespace rack::rt
