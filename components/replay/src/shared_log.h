// One recorded log shared by the replay components of a host, with one replay clock:
// a ChassisReplay and a LadarReplay that name the same file play it in step, whichever
// is switched on first. Private to the replay target.
//
// Real-time contract: acquire_shared_log() is not RT-safe (init: reads the file,
// allocates, locks). start() and host_time() are RT-safe (atomics only).
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
  // Host time (ns) at which a record of log time `t` (s) plays. Valid after start().
  [[nodiscard]] int64_t host_time(double t) const noexcept;

 private:
  LoadLogResult loaded_;
  double speed_;
  double t0_;
  // The host time of the first record; 0 until started. Acquire/release: only the
  // value itself is shared; CAS makes exactly one component's start() win.
  std::atomic<int64_t> anchor_ns_{0};
};

// The shared log for `path` (loaded at the first call in this process). Throws
// std::runtime_error with the file's errors (file:line: reason) when it does not load,
// or when another component plays the same file at another speed. With
// `strict` false, malformed lines are skipped (and reported to stderr) instead.
std::shared_ptr<SharedLog> acquire_shared_log(const std::string& path, double speed, bool strict);

}  // namespace rack::replay
