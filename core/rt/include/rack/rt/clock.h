// Time for RACK-RT: 64-bit nanoseconds.
//
// Periods and deadlines use CLOCK_MONOTONIC. Timestamps in data samples use the
// host clock (CLOCK_REALTIME) that PTP or chrony synchronise across hosts.
//
// A virtual clock for tests (Orocos' SlaveActivity, rack/core/stepper.h): while a
// VirtualClock exists, monotonic_ns() and host_time_ns() read it instead of the
// kernel, and the stepping thread's sleeps move it instead of sleeping. The task loops,
// the components and the mailboxes' logic all ask monotonic_ns(), so a test that
// steps an executor (ExecutorOptions::stepped) drives every deadline, period,
// watchdog and silence limit with advance(). Without one installed (rackd, every
// threaded test) the only cost is one load of a null pointer and a branch
// predicted not taken per clock read (bench/bench_clock.cpp, bench/RESULTS.md).
// Waits the kernel times (a mailbox receive's timeout, an RPC's, a futex) always run
// on the real clock: os_monotonic_ns().
//
// Real-time contract: every function here is real-time safe (no allocation, no
// lock, only vDSO clock reads or clock_nanosleep), VirtualClock's members too
// (atomics); constructing and destroying a VirtualClock is not (tests only).
#pragma once

#include <atomic>
#include <cstdint>
#include <ctime>

namespace rack::rt {

inline constexpr int64_t kNsPerUs = 1'000;
inline constexpr int64_t kNsPerMs = 1'000'000;
inline constexpr int64_t kNsPerSec = 1'000'000'000;

// CLOCK_MONOTONIC in ns, or the installed VirtualClock's time. RT-safe.
[[nodiscard]] int64_t monotonic_ns() noexcept;

// CLOCK_REALTIME in ns (the host clock used for sample timestamps), or the
// installed VirtualClock's host time. RT-safe.
[[nodiscard]] int64_t host_time_ns() noexcept;

// CLOCK_MONOTONIC in ns, whatever is installed: for deadlines that the kernel waits
// on (futex, clock_nanosleep), which must not be virtual. RT-safe.
[[nodiscard]] int64_t os_monotonic_ns() noexcept;

[[nodiscard]] constexpr timespec to_timespec(int64_t ns) noexcept {
  return timespec{static_cast<time_t>(ns / kNsPerSec), static_cast<long>(ns % kNsPerSec)};
}
[[nodiscard]] constexpr int64_t from_timespec(const timespec& ts) noexcept {
  return static_cast<int64_t>(ts.tv_sec) * kNsPerSec + ts.tv_nsec;
}

// Sleeps until the absolute CLOCK_MONOTONIC time (TIMER_ABSTIME), retrying on EINTR,
// and returns the monotonic time read right after the kernel returned: the wake-up, taken
// where cyclictest takes it, before the caller's own code touches its (possibly cold)
// state. With a VirtualClock installed, on the thread that installed it (the stepping
// one): moves it to `deadline_ns` (if later) and returns its time at once; elsewhere see
// VirtualClock.
// RT-safe (clock_nanosleep is the one blocking call a periodic task makes).
int64_t sleep_until_monotonic(int64_t deadline_ns) noexcept;

// Relative sleep on CLOCK_MONOTONIC (or the VirtualClock, as above). RT-safe.
void sleep_for(int64_t duration_ns) noexcept;

// A clock that moves only when told to, installed for the process while it exists
// (one at a time: a second one throws std::logic_error), for tests that step an executor
// (rack/core/stepper.h). Only its installing thread's sleeps move it; another thread's
// sleep waits as long on the kernel's clock (a real thread's sleep is not time passing).
//
//   rt::VirtualClock clock;                 // monotonic_ns() == clock.now_ns() now
//   clock.advance(10 * rt::kNsPerMs);       // 10 ms later, for every reader
//
// Construction and destruction: not RT-safe (test thread). now_ns(), host_ns(),
// advance(), advance_to(): RT-safe, any thread.
class VirtualClock {
 public:
  // The monotonic time it starts at, and the host time (CLOCK_REALTIME) at that
  // moment: fixed values, so that a test's timestamps are the same in every run.
  static constexpr int64_t kDefaultStartNs = 1'000 * kNsPerSec;
  static constexpr int64_t kDefaultHostStartNs = 1'790'000'000 * kNsPerSec;  // September 2026 (UTC)
  explicit VirtualClock(int64_t start_ns = kDefaultStartNs, int64_t host_start_ns = kDefaultHostStartNs);
  ~VirtualClock();
  VirtualClock(const VirtualClock&) = delete;
  VirtualClock& operator=(const VirtualClock&) = delete;

  [[nodiscard]] int64_t now_ns() const noexcept { return now_ns_.load(std::memory_order_acquire); }
  [[nodiscard]] int64_t host_ns() const noexcept { return now_ns() + host_offset_ns_; }
  // Moves the time forward by `ns` (negative: nothing). Returns the new time.
  int64_t advance(int64_t ns) noexcept;
  // Moves the time to `t_ns` when that is later (it never goes back). Returns the time.
  int64_t advance_to(int64_t t_ns) noexcept;

 private:
  // acquire/release: a reader that sees a time also sees what the advancing thread
  // wrote before it (a stepped test has one thread; the GDOS thread reads it too).
  std::atomic<int64_t> now_ns_;
  int64_t host_offset_ns_;
};

// The installed VirtualClock, or nullptr (the kernel's clocks). RT-safe.
[[nodiscard]] VirtualClock* virtual_clock() noexcept;

}  // namespace rack::rt
