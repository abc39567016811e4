// A mutex with priority inheritance and a condition variable on CLOCK_MONOTONIC.
//
// Real-time code may only lock mutexes with priority inheritance (PTHREAD_PRIO_INHERIT):
// a low-priority holder is boosted while a high-priority task waits, so the wait is
// bounded by the critical section. Keep critical sections short and bounded.
//
// The condition variable is a futex sequence word, not pthread_cond_t: after a
// pthread_cond_wait glibc re-acquires a PI mutex with FUTEX_WAITERS forced on, so the
// next unlock of that mutex is a FUTEX_UNLOCK_PI system call even when nobody waits
// (bench/RESULTS.md, "System calls per round trip"). Here the mutex is re-locked
// normally (a user-space CAS when uncontended) and a notify with no waiter makes no
// system call. The kernel wakes futex waiters in priority order.
//
// Real-time contract: lock/unlock/wait/notify are RT-safe. Construction is not.
#pragma once

#include <pthread.h>

#include <atomic>
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
  PiCondVar() = default;
  ~PiCondVar() = default;
  PiCondVar(const PiCondVar&) = delete;
  PiCondVar& operator=(const PiCondVar&) = delete;

  // Waits with `mutex` held until notified or until the absolute CLOCK_MONOTONIC
  // deadline (ns); deadline < 0 waits without limit. Returns false on timeout.
  // Spurious wake-ups happen: callers re-check their predicate. RT-safe.
  bool wait_until(PiMutex& mutex, int64_t deadline_ns) noexcept;
  // Wake one or all waiters. The state they wait for must have been changed under
  // the same mutex (before or after this call); the call itself may be made with or
  // without the mutex held. RT-safe.
  void notify_one() noexcept;
  void notify_all() noexcept;

 private:
  void wake(int count) noexcept;
  // SYNC POINT: a waiter registers in waiters_ and samples seq_ while it holds the
  // mutex, then sleeps only while seq_ is unchanged; a notifier bumps seq_ then reads
  // waiters_ (both seq_cst). A notifier that changed the state under the mutex after
  // the waiter released it therefore sees the waiter registered, and the waiter's
  // futex wait returns at once if the bump came first: no lost wake-up.
  std::atomic<uint32_t> seq_{0};
  std::atomic<uint32_t> waiters_{0};
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
