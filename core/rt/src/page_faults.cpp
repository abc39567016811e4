#include "rack/rt/page_faults.h"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace rack::rt {

FaultCount read_thread_faults(pid_t tid) noexcept {
  FaultCount c;
  char path[64];
  std::snprintf(path, sizeof path, "/proc/self/task/%d/stat", static_cast<int>(tid));
  // open/read into a stack buffer: the GDOS thread samples every second and must not
  // allocate (the no-allocation tests count every thread).
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return c;
  char buf[1024];
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  if (n <= 0) return c;
  buf[n] = '\0';
  // Field 2 (comm) is in parentheses and may hold spaces: count fields after the last ')'.
  const char* p = std::strrchr(buf, ')');
  if (p == nullptr) return c;
  ++p;
  // Fields from 3 on: state(3) ppid pgrp session tty_nr tpgid flags minflt(10) cminflt majflt(12).
  uint64_t fields[10] = {};
  int field = 3;
  while (*p != '\0' && field <= 12) {
    while (*p == ' ') ++p;
    char* end = nullptr;
    if (field == 3) {
      while (*p != '\0' && *p != ' ') ++p;  // the state letter
    } else {
      const unsigned long long v = std::strtoull(p, &end, 10);
      if (end == p) return c;
      fields[field - 3] = v;
      p = end;
    }
    ++field;
  }
  if (field <= 12) return c;
  c.minor = fields[10 - 3];
  c.major = fields[12 - 3];
  c.measured = true;
  return c;
}

void TaskFaults::mark_started() noexcept {
  rusage u{};
  if (::getrusage(RUSAGE_THREAD, &u) == 0) {
    base_minor_.store(static_cast<uint64_t>(u.ru_minflt), std::memory_order_relaxed);
    base_major_.store(static_cast<uint64_t>(u.ru_majflt), std::memory_order_relaxed);
  }
  tid_.store(static_cast<pid_t>(::gettid()), std::memory_order_release);
}

FaultCount TaskFaults::sample() noexcept {
  const pid_t tid = tid_.load(std::memory_order_acquire);
  if (tid == 0) return {};
  const FaultCount now = read_thread_faults(tid);
  if (!now.measured) return last();  // the thread has ended: keep the last figures
  const uint64_t bmin = base_minor_.load(std::memory_order_relaxed);
  const uint64_t bmaj = base_major_.load(std::memory_order_relaxed);
  minor_.store(now.minor >= bmin ? now.minor - bmin : 0, std::memory_order_relaxed);
  major_.store(now.major >= bmaj ? now.major - bmaj : 0, std::memory_order_relaxed);
  sampled_.store(true, std::memory_order_release);
  return last();
}

FaultCount TaskFaults::last() const noexcept {
  FaultCount c;
  if (!sampled_.load(std::memory_order_acquire)) return c;
  c.minor = minor_.load(std::memory_order_relaxed);
  c.major = major_.load(std::memory_order_relaxed);
  c.measured = true;
  return c;
}

}  // namespace rack::rt
