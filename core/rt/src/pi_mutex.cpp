#include "rack/rt/pi_mutex.h"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>

#include "rack/rt/clock.h"
#include "rack/rt/modeswitch.h"

namespace rack::rt {

PiMutex::PiMutex() {
  pthread_mutexattr_t attr;
  pthread_mutexattr_init(&attr);
  pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_INHERIT);
  if (pthread_mutex_init(&mutex_, &attr) != 0) std::abort();
  pthread_mutexattr_destroy(&attr);
}

PiMutex::~PiMutex() { pthread_mutex_destroy(&mutex_); }
// The TrustedScopes: a PI mutex and its condition variable are the framework's RT-safe
// way to wait; their futex calls are not mode switches (see modeswitch.h).
void PiMutex::lock() noexcept {
  modeswitch::TrustedScope trusted;
  if (pthread_mutex_trylock(&mutex_) == 0) return;
  modeswitch::TrustedScope waiting(true);  // contended: this cycle may block here
  pthread_mutex_lock(&mutex_);
}
void PiMutex::unlock() noexcept {
  modeswitch::TrustedScope trusted;
  pthread_mutex_unlock(&mutex_);
}
bool PiMutex::try_lock() noexcept { return pthread_mutex_trylock(&mutex_) == 0; }

bool PiCondVar::wait_until(PiMutex& mutex, int64_t deadline_ns) noexcept {
  modeswitch::TrustedScope trusted(true);
  waiters_.fetch_add(1, std::memory_order_seq_cst);
  const uint32_t seen = seq_.load(std::memory_order_seq_cst);
  mutex.unlock();
  timespec ts{};
  const timespec* timeout = nullptr;
  if (deadline_ns >= 0) {
    ts = to_timespec(deadline_ns);
    timeout = &ts;
  }
  // FUTEX_WAIT_BITSET takes an absolute timeout on CLOCK_MONOTONIC (without
  // FUTEX_CLOCK_REALTIME). EAGAIN: seq_ moved since we sampled it (a notify came).
  const long r = ::syscall(SYS_futex, &seq_, FUTEX_WAIT_BITSET_PRIVATE, seen, timeout, nullptr, FUTEX_BITSET_MATCH_ANY);
  const bool timed_out = r != 0 && errno == ETIMEDOUT;
  waiters_.fetch_sub(1, std::memory_order_relaxed);
  mutex.lock();
  return !timed_out;
}

void PiCondVar::wake(int count) noexcept {
  seq_.fetch_add(1, std::memory_order_seq_cst);
  if (waiters_.load(std::memory_order_seq_cst) == 0) return;  // nobody asleep: no system call
  modeswitch::TrustedScope trusted;
  ::syscall(SYS_futex, &seq_, FUTEX_WAKE_PRIVATE, count, nullptr, nullptr, 0);
}

void PiCondVar::notify_one() noexcept { wake(1); }
void PiCondVar::notify_all() noexcept { wake(INT32_MAX); }

}  // namespace rack::rt
