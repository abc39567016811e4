#include "rack/rt/pi_mutex.h"

#include <cerrno>
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

PiCondVar::PiCondVar() {
  pthread_condattr_t attr;
  pthread_condattr_init(&attr);
  pthread_condattr_setclock(&attr, CLOCK_MONOTONIC);
  if (pthread_cond_init(&cond_, &attr) != 0) std::abort();
  pthread_condattr_destroy(&attr);
}

PiCondVar::~PiCondVar() { pthread_cond_destroy(&cond_); }

bool PiCondVar::wait_until(PiMutex& mutex, int64_t deadline_ns) noexcept {
  modeswitch::TrustedScope trusted(true);
  if (deadline_ns < 0) {
    pthread_cond_wait(&cond_, mutex.native());
    return true;
  }
  const timespec ts = to_timespec(deadline_ns);
  return pthread_cond_timedwait(&cond_, mutex.native(), &ts) != ETIMEDOUT;
}

void PiCondVar::notify_one() noexcept {
  modeswitch::TrustedScope trusted;
  pthread_cond_signal(&cond_);
}
void PiCondVar::notify_all() noexcept {
  modeswitch::TrustedScope trusted;
  pthread_cond_broadcast(&cond_);
}

}  // namespace rack::rt
