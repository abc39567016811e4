// A short history of a scalar signal with timestamps (a servo drive's position
// stream), interpolated at any time inside it: Scan3D and LadarSim need the drive's
// angle at the moment of each laser beam, which falls between two drive samples.
// The ring and its look-up (StampedSeries) also serve pose_series.h (robot poses).
//
// Real-time contract: RT-safe (fixed capacity, no allocation); one thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace rack::components {

enum class SeriesLookup : uint8_t {
  kOk,      // inside the history (interpolated), or within max_extrapolation_ns after its end
  kTooOld,  // before the oldest sample: that moment is lost
  kTooNew,  // after the newest sample (+ max_extrapolation_ns): wait for more samples
  kEmpty,
};

// The ring both series below share: samples (time, value) in time order, the newest
// N kept; lookup() finds the two around a time and lets the series interpolate.
template <typename Value, std::size_t N>
class StampedSeries {
 public:
  void clear() noexcept {
    count_ = 0;
    head_ = 0;
  }
  [[nodiscard]] std::size_t size() const noexcept { return count_; }
  [[nodiscard]] int64_t oldest_time() const noexcept { return count_ ? at(0).t : 0; }
  [[nodiscard]] int64_t newest_time() const noexcept { return count_ ? at(count_ - 1).t : 0; }

  // Appends a sample; one that is not newer than the newest is ignored (false).
  bool push(int64_t t, const Value& v) noexcept {
    if (count_ > 0 && t <= newest_time()) return false;
    const std::size_t slot = (head_ + count_) % N;
    items_[slot] = Item{t, v};
    if (count_ < N) ++count_;
    else head_ = (head_ + 1) % N;
    return true;
  }

 protected:
  // The value at time t: `lerp(a, b, f)` between the two samples around t; past the
  // newest, that sample held for up to hold_ns.
  template <typename Lerp>
  [[nodiscard]] SeriesLookup lookup(int64_t t, int64_t hold_ns, Value& out, Lerp lerp) const noexcept {
    if (count_ == 0) return SeriesLookup::kEmpty;
    if (t < at(0).t) return SeriesLookup::kTooOld;
    const Item& last = at(count_ - 1);
    if (t >= last.t) {
      if (t - last.t > hold_ns) return SeriesLookup::kTooNew;
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
    out = lerp(a.v, b.v, static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t));
    return SeriesLookup::kOk;
  }
  [[nodiscard]] const Value& newest() const noexcept { return at(count_ - 1).v; }

 private:
  struct Item {
    int64_t t = 0;
    Value v{};
  };
  [[nodiscard]] const Item& at(std::size_t i) const noexcept { return items_[(head_ + i) % N]; }
  std::array<Item, N> items_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
};

template <std::size_t N = 512>
class TimeSeries : public StampedSeries<double, N> {
 public:
  [[nodiscard]] double newest_value() const noexcept { return this->size() ? this->newest() : 0.0; }

  // The value at time t: linear between the two samples around t; past the newest,
  // held constant for up to max_extrapolation_ns (a drive that stands still sends its
  // samples periodically, so a short hold is exact for it).
  [[nodiscard]] SeriesLookup value_at(int64_t t, int64_t max_extrapolation_ns, double& out) const noexcept {
    return this->lookup(t, max_extrapolation_ns, out, [](double a, double b, double f) { return a + f * (b - a); });
  }
};

}  // namespace rack::components
