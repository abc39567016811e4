// Time for RACK-RT: 64-bit nanoseconds.
//
// Periods and deadlines use CLOCK_MONOTONIC. Timestamps in data samples use the
// host clock (CLOCK_REALTIME) that PTP or chrony synchronise across hosts.
//
// Real-time contract: every function here is real-time safe (no allocation, no
// lock, only vDSO clock reads or clock_nanosleep).
#pragma once

#include <cstdint>
#include <ctime>

namespace rack::rt {

inline constexpr int64_t kNsPerUs = 1'000;
inline constexpr int64_t kNsPerMs = 1'000'000;
inline constexpr int64_t kNsPerSec = 1'000'000'000;

// CLOCK_MONOTONIC in ns. RT-safe.
[[nodiscard]] int64_t monotonic_ns() noexcept;

// CLOCK_REALTIME in ns (the host clock used for sample timestamps). RT-safe.
[[nodiscard]] int64_t host_time_ns() noexcept;

[[nodiscard]] constexpr timespec to_timespec(int64_t ns) noexcept {
  return timespec{static_cast<time_t>(ns / kNsPerSec), static_cast<long>(ns % kNsPerSec)};
}
[[nodiscard]] constexpr int64_t from_timespec(const timespec& ts) noexcept {
  return static_cast<int64_t>(ts.tv_sec) * kNsPerSec + ts.tv_nsec;
}

// Sleeps until the absolute CLOCK_MONOTONIC time (TIMER_ABSTIME), retrying on EINTR.
// RT-safe (clock_nanosleep is the one blocking call a periodic task makes).
void sleep_until_monotonic(int64_t deadline_ns) noexcept;

// Relative sleep on CLOCK_MONOTONIC. RT-safe.
void sleep_for(int64_t duration_ns) noexcept;

}  // namespace rack::rt
