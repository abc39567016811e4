// Per-task timing statistics: wake-up latency histogram, cycle and overrun counts.
//
// Thread-safety: single writer (the task that owns it), any number of readers.
// The writer only does relaxed loads and stores (no read-modify-write): a reader may
// see a snapshot a few samples old, which is fine for statistics.
// Real-time contract: record_*() are RT-safe (no allocation, no lock, no syscall).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace rack::rt {

struct LatencySummary {
  uint64_t cycles = 0;
  uint64_t overruns = 0;     // periods missed (skipped, never caught up)
  uint64_t samples = 0;      // latency samples in the histogram
  int64_t min_ns = 0;
  int64_t max_ns = 0;
  int64_t p50_ns = 0;
  int64_t p99_ns = 0;
  int64_t p999_ns = 0;
  int64_t mean_ns = 0;
};

class LatencyStats {
 public:
  static constexpr int64_t kBucketNs = 1'000;     // 1 us resolution
  static constexpr std::size_t kBuckets = 10'000;  // up to 10 ms; beyond goes to the last bucket

  void record_latency(int64_t ns) noexcept;     // RT-safe, writer only
  void record_cycle() noexcept;                 // RT-safe, writer only
  void record_overruns(uint64_t n) noexcept;    // RT-safe, writer only
  void reset() noexcept;                        // not while the writer runs

  [[nodiscard]] LatencySummary summary() const noexcept;  // any thread; O(kBuckets)
  // Copies the bucket counts (index i: latency in [i, i+1) us; last: >= kBuckets-1 us).
  void copy_histogram(std::array<uint64_t, kBuckets>& out) const noexcept;

 private:
  // Relaxed everywhere: each counter is independent; readers want eventual values.
  std::array<std::atomic<uint64_t>, kBuckets> buckets_{};
  std::atomic<uint64_t> cycles_{0};
  std::atomic<uint64_t> overruns_{0};
  std::atomic<uint64_t> samples_{0};
  std::atomic<int64_t> sum_ns_{0};
  std::atomic<int64_t> min_ns_{INT64_MAX};
  std::atomic<int64_t> max_ns_{0};
};

}  // namespace rack::rt
