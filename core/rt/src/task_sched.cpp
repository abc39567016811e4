#include "rack/rt/task_sched.h"

#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "rack/rt/clock.h"

namespace rack::rt {

SchedInfo read_thread_sched(pid_t tid) noexcept {
  SchedInfo s;
  if (tid <= 0) return s;
  char path[64];
  std::snprintf(path, sizeof path, "/proc/self/task/%d/stat", static_cast<int>(tid));
  // A stack buffer, as read_thread_faults: the GDOS thread samples every second and
  // must not allocate (the no-allocation tests count every thread).
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return s;
  char buf[1024];
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  if (n <= 0) return s;
  buf[n] = '\0';
  // Field 2 (comm) is in parentheses and may hold spaces: count fields after the last ')'.
  const char* p = std::strrchr(buf, ')');
  if (p == nullptr) return s;
  ++p;
  // Fields 3 (state, a letter) to 41: processor (39), rt_priority (40), policy (41).
  long long fields[3] = {-1, -1, -1};
  int field = 3;
  while (*p != '\0' && field <= 41) {
    while (*p == ' ') ++p;
    if (*p == '\0') break;
    const char* start = p;
    while (*p != '\0' && *p != ' ' && *p != '\n') ++p;
    if (field >= 39) {
      char* end = nullptr;
      const long long v = std::strtoll(start, &end, 10);
      if (end != p) return s;
      fields[field - 39] = v;
    }
    ++field;
  }
  if (field <= 41) return s;
  if (fields[0] < 0 || fields[1] < 0 || fields[1] > 99 || fields[2] < 0 || fields[2] > 255) return s;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(tid, sizeof set, &set) != 0) return s;
  for (std::size_t c = 0; c < SchedInfo::kCpuWords * 64; ++c) {
    if (CPU_ISSET(c, &set)) s.affinity[c / 64] |= uint64_t{1} << (c % 64);
  }
  const long online = ::sysconf(_SC_NPROCESSORS_ONLN);
  s.last_cpu = static_cast<int>(fields[0]);
  s.priority = static_cast<int>(fields[1]);
  s.policy = static_cast<int>(fields[2]);
  s.online_cpus = online > 0 && online < 1'000'000 ? static_cast<int>(online) : 0;
  s.time_ns = monotonic_ns();
  s.measured = true;
  return s;
}

void TaskSched::sample(pid_t tid) noexcept {
  if (tid == 0) return;
  const SchedInfo s = read_thread_sched(tid);
  if (!s.measured) return;  // the thread has ended: keep the last reading
  const uint32_t seq = seq_.load(std::memory_order_relaxed);
  seq_.store(seq + 1, std::memory_order_relaxed);
  // The odd value is visible before any field changes.
  std::atomic_thread_fence(std::memory_order_release);
  policy_.store(s.policy, std::memory_order_relaxed);
  priority_.store(s.priority, std::memory_order_relaxed);
  last_cpu_.store(s.last_cpu, std::memory_order_relaxed);
  online_cpus_.store(s.online_cpus, std::memory_order_relaxed);
  for (std::size_t w = 0; w < SchedInfo::kCpuWords; ++w) affinity_[w].store(s.affinity[w], std::memory_order_relaxed);
  time_ns_.store(s.time_ns, std::memory_order_relaxed);
  measured_.store(true, std::memory_order_relaxed);
  seq_.store(seq + 2, std::memory_order_release);  // publishes the fields
}

SchedInfo TaskSched::last() const noexcept {
  for (int attempt = 0; attempt < kTries; ++attempt) {
    const uint32_t before = seq_.load(std::memory_order_acquire);  // pairs with sample()'s release
    if ((before & 1u) != 0) continue;
    SchedInfo s;
    s.measured = measured_.load(std::memory_order_relaxed);
    s.policy = policy_.load(std::memory_order_relaxed);
    s.priority = priority_.load(std::memory_order_relaxed);
    s.last_cpu = last_cpu_.load(std::memory_order_relaxed);
    s.online_cpus = online_cpus_.load(std::memory_order_relaxed);
    for (std::size_t w = 0; w < SchedInfo::kCpuWords; ++w) s.affinity[w] = affinity_[w].load(std::memory_order_relaxed);
    s.time_ns = time_ns_.load(std::memory_order_relaxed);
    // The field loads happen before the second look at the sequence.
    std::atomic_thread_fence(std::memory_order_acquire);
    if (seq_.load(std::memory_order_relaxed) == before) return s;
  }
  return {};
}

}  // namespace rack::rt
