// A short history of a scalar signal with timestamps (a servo drive's position
// stream), interpolated at any time inside it: Scan3D and LadarSim need the drive's
// angle at the moment of each laser beam, which falls between two drive samples.
//
// Real-time contract: RT-safe (fixed capacity, no allocation); one thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace rack::components {

enum class SeriesLookup : uint8_t {
  kOk,        // inside the history (interpolated), or within max_extrapolation_ns after its end
  kTooOld,    // before the oldest sample: that moment is lost
  kTooNew,    // after the newest sample (+ max_extrapolation_ns): wait for more samples
  kEmpty,
};

template <std::size_t N = 512>
class TimeSeries {
 public:
  void clear() noexcept { count_ = 0; head_ = 0; }
  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  [[nodiscard]] int64_t newest_time() const noexcept { return count_ ? at(count_ - 1).t : 0; }
  [[nodiscard]] double newest_value() const noexcept { return count_ ? at(count_ - 1).v : 0.0; }

  // Appends a sample; one that is not newer than the newest is ignored (false).
  bool push(int64_t t, double v) noexcept {
    if (count_ > 0 && t <= newest_time()) return false;
    const std::size_t slot = (head_ + count_) % N;
    items_[slot] = Item{t, v};
    if (count_ < N) ++count_;
    else head_ = (head_ + 1) % N;
    return true;
  }

  // The value at time t: linear between the two samples around t; past the newest,
  // held constant for up to max_extrapolation_ns (a drive that stands still sends its
  // samples periodically, so a short hold is exact for it).
  [[nodiscard]] SeriesLookup value_at(int64_t t, int64_t max_extrapolation_ns, double& out) const noexcept {
    if (count_ == 0) return SeriesLookup::kEmpty;
    if (t < at(0).t) return SeriesLookup::kTooOld;
    const Item& last = at(count_ - 1);
    if (t >= last.t) {
      if (t - last.t > max_extrapolation_ns) return SeriesLookup::kTooNew;
      out = last.v;
      return SeriesLookup::kOk;
    }
    // Binary search for the last sample at or before t.
    std::size_t lo = 0, hi = count_ - 1;  // at(lo).t <= t < at(hi).t
    while (hi - lo > 1) {
      const std::size_t mid = (lo + hi) / 2;
      if (at(mid).t <= t) lo = mid;
      else hi = mid;
    }
    const Item& a = at(lo);
    const Item& b = at(hi);
    const double f = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
    out = a.v + f * (b.v - a.v);
    return SeriesLookup::kOk;
  }

 private:
  struct Item {
    int64_t t = 0;
    double v = 0.0;
  };
  [[nodiscard]] const Item& at(std::size_t i) const noexcept { return items_[(head_ + i) % N]; }
  std::array<Item, N> items_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
};

}  // namespace rack::components
