#include "rack/rt/clock.h"

#include <cerrno>

#include "rack/rt/modeswitch.h"

namespace rack::rt {

int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return from_timespec(ts);
}

int64_t host_time_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return from_timespec(ts);
}

void sleep_until_monotonic(int64_t deadline_ns) noexcept {
  const timespec ts = to_timespec(deadline_ns);
  modeswitch::TrustedScope trusted(true);  // the one blocking call a periodic task makes
  // clock_nanosleep returns the error number directly (not via errno).
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void sleep_for(int64_t duration_ns) noexcept {
  if (duration_ns <= 0) return;
  sleep_until_monotonic(monotonic_ns() + duration_ns);
}

}  // namespace rack::rt
