#include "shared_log.h"

#include <cmath>
#include <map>
#include <mutex>
#include <stdexcept>

namespace rack::replay {

SharedLog::SharedLog(LoadLogResult loaded, double speed)
    : loaded_(std::move(loaded)), speed_(speed), t0_(loaded_.log.first_time()) {}

int64_t SharedLog::start(int64_t now_ns) noexcept {
  int64_t expected = 0;
  if (anchor_ns_.compare_exchange_strong(expected, now_ns, std::memory_order_acq_rel)) return now_ns;
  return expected;
}

int64_t SharedLog::host_time(double t) const noexcept {
  if (!(speed_ > 0.0)) return anchor_ns_.load(std::memory_order_acquire);
  return anchor_ns_.load(std::memory_order_acquire) + static_cast<int64_t>(std::llround((t - t0_) / speed_ * 1e9));
}

int64_t SharedLog::sample_time(double t) noexcept { return static_cast<int64_t>(std::llround(t * 1e9)); }

std::shared_ptr<SharedLog> acquire_shared_log(const std::string& path, double speed, bool strict,
                                              std::string& skipped) {
  skipped.clear();
  static std::mutex mutex;
  static std::map<std::string, std::weak_ptr<SharedLog>> logs;
  std::lock_guard lock(mutex);
  if (auto existing = logs[path].lock()) {
    if (std::fabs(existing->speed() - speed) > 1e-9) {
      throw std::runtime_error(path + ": already replayed at speed " + std::to_string(existing->speed()) +
                               " by another component; give both the same 'speed'");
    }
    return existing;
  }
  LoadLogResult loaded = load_replay_log(path);
  const bool fatal = !loaded.errors.empty() && (strict || (loaded.log.scans.empty() && loaded.log.odometry.empty()));
  if (fatal) throw std::runtime_error(loaded.error_text(5));
  // Samples carry the log's time: it must be positive and fit int64 nanoseconds.
  const double first = loaded.log.first_time(), last = loaded.log.last_time();
  if (!(first > 0.0) || !(last < 9.0e9)) {
    throw std::runtime_error(path + ": record times must lie in (0, 9e9) s (they become the samples' times); found " +
                             std::to_string(first) + " .. " + std::to_string(last));
  }
  if (!loaded.errors.empty()) {
    skipped = std::to_string(loaded.errors.size()) + " malformed line(s) skipped (strict: false):\n" +
              loaded.error_text(5);
  }
  auto shared = std::make_shared<SharedLog>(std::move(loaded), speed);
  logs[path] = shared;
  return shared;
}

}  // namespace rack::replay
