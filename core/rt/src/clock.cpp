#include "rack/rt/clock.h"

#include <pthread.h>

#include <cerrno>
#include <stdexcept>

#include "rack/rt/modeswitch.h"

namespace rack::rt {

namespace {
// The installed VirtualClock. Relaxed would do on every target we build for (a
// pointer load); acquire pairs with the release in the constructor so that a task
// that sees the pointer also sees the clock's initial time.
std::atomic<VirtualClock*> g_virtual{nullptr};
// The thread that installed it: the one that steps (rack/core/stepper.h), whose sleeps
// are time passing. pthread_t is an unsigned long here (lock-free); written after the
// install, so another thread may read the previous owner a moment: it is not this one.
std::atomic<pthread_t> g_owner{};

int64_t read(clockid_t id) noexcept {
  timespec ts{};
  clock_gettime(id, &ts);
  return from_timespec(ts);
}

// Sleeps on the kernel's clock until `deadline_ns` of CLOCK_MONOTONIC, retrying on EINTR,
// and returns CLOCK_MONOTONIC read right after the kernel returned (the wake-up).
int64_t kernel_sleep_until(int64_t deadline_ns) noexcept {
  const timespec ts = to_timespec(deadline_ns);
  modeswitch::TrustedScope trusted(true);  // the one blocking call a periodic task makes
  // clock_nanosleep returns the error number directly (not via errno).
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
  return read(CLOCK_MONOTONIC);
}
}  // namespace

int64_t monotonic_ns() noexcept {
  // One load and a branch predicted not taken: the real-time path pays no more
  // (bench/bench_clock.cpp measures it against the plain clock read).
  if (const VirtualClock* v = g_virtual.load(std::memory_order_acquire); v != nullptr) [[unlikely]] {
    return v->now_ns();
  }
  return read(CLOCK_MONOTONIC);
}

int64_t host_time_ns() noexcept {
  if (const VirtualClock* v = g_virtual.load(std::memory_order_acquire); v != nullptr) [[unlikely]] {
    return v->host_ns();
  }
  return read(CLOCK_REALTIME);
}

int64_t os_monotonic_ns() noexcept { return read(CLOCK_MONOTONIC); }

VirtualClock* virtual_clock() noexcept { return g_virtual.load(std::memory_order_acquire); }

int64_t sleep_until_monotonic(int64_t deadline_ns) noexcept {
  if (VirtualClock* v = g_virtual.load(std::memory_order_acquire); v != nullptr) [[unlikely]] {
    // Only the stepping thread's sleep is time passing. Any other thread (LCM's, an I/O
    // worker) sleeps as long on the kernel's clock and moves nothing: LcmTransport's
    // maintenance loop (rt::sleep_for(50 ms) a turn) moved the clock 50 ms a turn at
    // full speed, minutes of virtual time within a stepped test's 51 ms (the CI failure
    // of PlaybackTest.LadarAndOdometryPlaybackFeedALiveScan2d...).
    if (pthread_equal(g_owner.load(std::memory_order_acquire), pthread_self()) != 0) {
      return v->advance_to(deadline_ns);
    }
    const int64_t left = deadline_ns - v->now_ns();
    if (left > 0) (void)kernel_sleep_until(os_monotonic_ns() + left);
    return v->now_ns();
  }
  return kernel_sleep_until(deadline_ns);
}

void sleep_for(int64_t duration_ns) noexcept {
  if (duration_ns <= 0) return;
  (void)sleep_until_monotonic(monotonic_ns() + duration_ns);
}

VirtualClock::VirtualClock(int64_t start_ns, int64_t host_start_ns)
    : now_ns_(start_ns), host_offset_ns_(host_start_ns - start_ns) {
  VirtualClock* expected = nullptr;
  if (!g_virtual.compare_exchange_strong(expected, this, std::memory_order_acq_rel)) {
    throw std::logic_error("rt::VirtualClock: another virtual clock is installed already");
  }
  g_owner.store(pthread_self(), std::memory_order_release);  // pairs with the sleeps' acquire
}

VirtualClock::~VirtualClock() {
  VirtualClock* self = this;
  (void)g_virtual.compare_exchange_strong(self, nullptr, std::memory_order_acq_rel);
}

int64_t VirtualClock::advance(int64_t ns) noexcept {
  if (ns <= 0) return now_ns();
  return now_ns_.fetch_add(ns, std::memory_order_acq_rel) + ns;
}

int64_t VirtualClock::advance_to(int64_t t_ns) noexcept {
  int64_t now = now_ns_.load(std::memory_order_acquire);
  while (now < t_ns && !now_ns_.compare_exchange_weak(now, t_ns, std::memory_order_acq_rel)) {
  }
  return now < t_ns ? t_ns : now;
}

}  // namespace rack::rt
