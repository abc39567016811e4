// A short history of the robot's 2-D pose (x, y, heading) with timestamps, from an
// Odometry or Position stream, interpolated at any time inside it: Scan3D needs the
// robot's pose at the moment of each laser beam to undo the robot's motion during a
// sweep (time_series.h is the same for a scalar).
//
// No extrapolation: a pose after the newest sample is unknown (a moving robot is not
// where it was), so a caller waits for the next sample.
//
// Real-time contract: RT-safe (fixed capacity inside the object, no allocation); one
// thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "common/pose2d.h"
#include "common/time_series.h"

namespace rack::components {

template <std::size_t N = 256>
class PoseSeries {
 public:
  void clear() noexcept { count_ = 0; head_ = 0; }
  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  [[nodiscard]] int64_t oldest_time() const noexcept { return count_ ? at(0).t : 0; }
  [[nodiscard]] int64_t newest_time() const noexcept { return count_ ? at(count_ - 1).t : 0; }

  // Appends a pose; one that is not newer than the newest is ignored (false). The
  // caller checks that it is finite.
  bool push(int64_t t, const Pose2d& p) noexcept {
    if (count_ > 0 && t <= newest_time()) return false;
    const std::size_t slot = (head_ + count_) % N;
    items_[slot] = Item{t, p};
    if (count_ < N) ++count_;
    else head_ = (head_ + 1) % N;
    return true;
  }

  // The pose at time t: x and y linear between the two samples around t, the heading
  // along the shorter way round. kTooOld before the oldest sample, kTooNew after the
  // newest, kEmpty without samples.
  [[nodiscard]] SeriesLookup pose_at(int64_t t, Pose2d& out) const noexcept {
    if (count_ == 0) return SeriesLookup::kEmpty;
    if (t < at(0).t) return SeriesLookup::kTooOld;
    const Item& last = at(count_ - 1);
    if (t >= last.t) {
      if (t > last.t) return SeriesLookup::kTooNew;
      out = last.p;
      return SeriesLookup::kOk;
    }
    std::size_t lo = 0, hi = count_ - 1;  // at(lo).t <= t < at(hi).t
    while (hi - lo > 1) {
      const std::size_t mid = (lo + hi) / 2;
      if (at(mid).t <= t) lo = mid;
      else hi = mid;
    }
    const Item& a = at(lo);
    const Item& b = at(hi);
    const double f = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
    out = Pose2d{a.p.x + f * (b.p.x - a.p.x), a.p.y + f * (b.p.y - a.p.y),
                 normalize_angle(a.p.phi + f * normalize_angle(b.p.phi - a.p.phi))};
    return SeriesLookup::kOk;
  }

 private:
  struct Item {
    int64_t t = 0;
    Pose2d p;
  };
  [[nodiscard]] const Item& at(std::size_t i) const noexcept { return items_[(head_ + i) % N]; }
  std::array<Item, N> items_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
};

}  // namespace rack::components
