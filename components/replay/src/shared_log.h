// One recorded log shared by the replay components of a host, with one replay clock:
// a ChassisReplay and a LadarReplay that name the same file play it in step, whichever
// is switched on first. Private to the replay target.
//
// Time base: samples carry the log's own time (sample_time(): seconds of the log as
// nanoseconds), whatever the speed, so a replay at any speed gives the same samples
// and a trajectory is written in the log's time without a mapping. The replay clock
// (host_time()) only decides when a record plays.
//
// Pacing (a LadarReplay with 'pace'): the LadarReplay releases scan k only when the
// paced component has output for scan k-1, and the ChassisReplay publishes odometry
// only up to the first record at or after the next scan to be released. Nothing in
// the pipeline then runs ahead of the slowest consumer, and nothing is skipped.
//
// Real-time contract: acquire_shared_log() is not RT-safe (init: reads the file,
// allocates, locks). Everything else is RT-safe (atomics only).
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "rack/replay/replay_log.h"

namespace rack::replay {

class SharedLog {
 public:
  SharedLog(LoadLogResult loaded, double speed);
  [[nodiscard]] const LoadLogResult& loaded() const noexcept { return loaded_; }
  [[nodiscard]] const ReplayLog& log() const noexcept { return loaded_.log; }
  [[nodiscard]] double speed() const noexcept { return speed_; }
  // Starts the replay clock at `now_ns` (host clock) unless it already runs. Returns the
  // host time of the log's first record.
  int64_t start(int64_t now_ns) noexcept;
  // Host time (ns) at which a record of log time `t` (s) plays. Valid after start()
  // and with speed() > 0 (speed 0: as fast as the pace allows, no clock).
  [[nodiscard]] int64_t host_time(double t) const noexcept;
  // The time a record of log time `t` (s) carries as a sample: the log's own, in ns.
  [[nodiscard]] static int64_t sample_time(double t) noexcept;

  // Pacing. A paced LadarReplay calls set_paced() in init(), set_ready() once the
  // paced component is ENABLED (the pipeline listens), and set_scans_released(n)
  // after publishing its n-th scan. Relaxed flags/counter with release/acquire: the
  // ChassisReplay only reads the values themselves.
  void set_paced() noexcept { paced_.store(true, std::memory_order_release); }
  [[nodiscard]] bool paced() const noexcept { return paced_.load(std::memory_order_acquire); }
  void set_ready() noexcept { ready_.store(true, std::memory_order_release); }
  [[nodiscard]] bool ready() const noexcept { return ready_.load(std::memory_order_acquire); }
  void set_scans_released(std::size_t n) noexcept { released_.store(n, std::memory_order_release); }
  [[nodiscard]] std::size_t scans_released() const noexcept { return released_.load(std::memory_order_acquire); }

 private:
  LoadLogResult loaded_;
  double speed_;
  double t0_;
  // The host time of the first record; 0 until started. Acquire/release: only the
  // value itself is shared; CAS makes exactly one component's start() win.
  std::atomic<int64_t> anchor_ns_{0};
  std::atomic<bool> paced_{false};
  std::atomic<bool> ready_{false};
  std::atomic<std::size_t> released_{0};
};

// The shared log for `path` (loaded at the first call in this process). Throws
// std::runtime_error with the file's errors (file:line: reason) when it does not load,
// when its first record's time is not positive (sample time 0 means "newest" in a
// GET_DATA), or when another component plays the same file at another speed. With
// `strict` false, malformed lines are skipped instead: `skipped` then says which (the
// first few, file:line: reason; filled only by the call that loaded the file, "" when
// none were skipped), for the caller to log.
std::shared_ptr<SharedLog> acquire_shared_log(const std::string& path, double speed, bool strict, std::string& skipped);

}  // namespace rack::replay
