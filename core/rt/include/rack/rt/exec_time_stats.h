// Execution time of a task's cycles (how long loop() ran), for periodic and triggered
// tasks alike: a fixed log-linear histogram, 32 sub-buckets per power of two (each
// bucket within 1/32 = 3 % of its value), exact below 64 ns, up to 2^41 ns (36 min;
// longer cycles count in the last bucket). Unlike LatencyStats (1-us buckets up to
// 10 ms, for wake-up jitter) it spans a 20-us Scan2D cycle and a 200-ms MCL update
// with the same relative resolution, in 9.5 KB.
//
// Thread-safety: single writer (the task that owns it), any number of readers; the
// writer does relaxed loads and stores only (no read-modify-write), so a reader may
// see a snapshot a few samples old, which is fine for statistics.
// Real-time contract: record() is RT-safe (no allocation, lock or syscall);
// summary() is RT-safe too (O(kBuckets) relaxed loads), any thread.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>

namespace rack::rt {

struct ExecTimeSummary {
  uint64_t samples = 0;
  int64_t p50_ns = 0;  // the upper edge of the bucket holding the percentile (at most max_ns)
  int64_t p99_ns = 0;
  int64_t max_ns = 0;
  int64_t mean_ns = 0;
};

class ExecTimeStats {
 public:
  static constexpr std::size_t kSub = 32;                             // sub-buckets per power of two
  static constexpr int kMaxBits = 41;                                 // values up to 2^41 - 1 ns
  static constexpr std::size_t kBuckets = kSub * (kMaxBits - 5 + 1);  // 1184

  // Bucket of a value: the value itself below 64; above, its top 6 bits.
  [[nodiscard]] static constexpr std::size_t bucket_of(uint64_t ns) noexcept {
    ns = std::min<uint64_t>(ns, (uint64_t{1} << kMaxBits) - 1);
    if (ns < 2 * kSub) return static_cast<std::size_t>(ns);
    const auto shift = static_cast<unsigned>(std::bit_width(ns)) - 6U;
    return kSub * (shift + 1U) + static_cast<std::size_t>((ns >> shift) - kSub);
  }
  // Smallest value of bucket i; the bucket holds [lower_of(i), lower_of(i + 1)).
  [[nodiscard]] static constexpr uint64_t lower_of(std::size_t i) noexcept {
    if (i < 2 * kSub) return i;
    const std::size_t shift = i / kSub - 1;
    return (i % kSub + kSub) << shift;
  }

  void record(int64_t ns) noexcept {  // writer only
    const uint64_t v = ns > 0 ? static_cast<uint64_t>(ns) : 0;
    auto& b = buckets_[bucket_of(v)];
    b.store(b.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    samples_.store(samples_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    sum_ns_.store(sum_ns_.load(std::memory_order_relaxed) + v, std::memory_order_relaxed);
    if (static_cast<int64_t>(v) > max_ns_.load(std::memory_order_relaxed)) {
      max_ns_.store(static_cast<int64_t>(v), std::memory_order_relaxed);
    }
  }

  [[nodiscard]] ExecTimeSummary summary() const noexcept {
    ExecTimeSummary s;
    uint64_t n = 0;
    for (const auto& b : buckets_) n += b.load(std::memory_order_relaxed);
    s.samples = n;
    s.max_ns = max_ns_.load(std::memory_order_relaxed);
    if (n == 0) return s;
    s.mean_ns = static_cast<int64_t>(sum_ns_.load(std::memory_order_relaxed) /
                                     std::max<uint64_t>(1, samples_.load(std::memory_order_relaxed)));
    const uint64_t at50 = (n + 1) / 2, at99 = n - n / 100;  // the ranks (1-based) of p50 and p99
    uint64_t seen = 0;
    bool have50 = false;
    for (std::size_t i = 0; i < kBuckets; ++i) {
      seen += buckets_[i].load(std::memory_order_relaxed);
      const auto upper = static_cast<int64_t>(lower_of(i + 1) - 1);
      if (!have50 && seen >= at50) {
        s.p50_ns = std::min(upper, s.max_ns);
        have50 = true;
      }
      if (seen >= at99) {
        s.p99_ns = std::min(upper, s.max_ns);
        break;
      }
    }
    return s;
  }

 private:
  // Relaxed everywhere: each counter is independent; readers want eventual values.
  std::array<std::atomic<uint64_t>, kBuckets> buckets_{};
  std::atomic<uint64_t> samples_{0};
  std::atomic<uint64_t> sum_ns_{0};
  std::atomic<int64_t> max_ns_{0};
};

}  // namespace rack::rt
