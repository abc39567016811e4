// A mutex with priority inheritance and a condition variable on CLOCK_MONOTONIC.
//
// Real-time code may only lock mutexes with priority inheritance (PTHREAD_PRIO_INHERIT):
// a low-priority holder is boosted while a high-priority task waits, so the wait is
// bounded by the critical section. Keep critical sections short and bounded.
//
// Real-time contract: lock/unlock/wait/notify are RT-safe. Construction is not.
#pragma once

#include <pthread.h>

#include <cstdint>

namespace rack::rt {

class PiMutex {
 public:
  PiMutex();
  ~PiMutex();
  PiMutex(const PiMutex&) = delete;
  PiMutex& operator=(const PiMutex&) = delete;

  void lock() noexcept;    // RT-safe (PI)
  void unlock() noexcept;  // RT-safe
  [[nodiscard]] bool try_lock() noexcept;
  pthread_mutex_t* native() noexcept { return &mutex_; }

 private:
  pthread_mutex_t mutex_{};
};

class PiCondVar {
 public:
  PiCondVar();
  ~PiCondVar();
  PiCondVar(const PiCondVar&) = delete;
  PiCondVar& operator=(const PiCondVar&) = delete;

  // Waits with `mutex` held until notified or until the absolute CLOCK_MONOTONIC
  // deadline (ns); deadline < 0 waits without limit. Returns false on timeout.
  // Spurious wake-ups happen: callers re-check their predicate. RT-safe.
  bool wait_until(PiMutex& mutex, int64_t deadline_ns) noexcept;
  void notify_one() noexcept;  // RT-safe
  void notify_all() noexcept;  // RT-safe

 private:
  pthread_cond_t cond_{};
};

// RAII lock for PiMutex. RT-safe.
class PiLock {
 public:
  explicit PiLock(PiMutex& m) noexcept : m_(m) { m_.lock(); }
  ~PiLock() { m_.unlock(); }
  PiLock(const PiLock&) = delete;
  PiLock& operator=(const PiLock&) = delete;

 private:
  PiMutex& m_;
};

}  // namespace rack::rt
