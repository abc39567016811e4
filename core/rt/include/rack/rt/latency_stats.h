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
#include <span>

namespace rack::rt {

struct LatencySummary {
  uint64_t cycles = 0;
  uint64_t overruns = 0;  // periods missed (skipped, never caught up)
  uint64_t samples = 0;   // latency samples in the histogram
  int64_t min_ns = 0;
  int64_t max_ns = 0;
  int64_t p50_ns = 0;
  int64_t p99_ns = 0;
  int64_t p999_ns = 0;
  int64_t mean_ns = 0;
};

class LatencyStats {
 public:
  static constexpr int64_t kBucketNs = 1'000;  // 1 us resolution
  // Buckets 0..9999: [i, i+1) us; bucket 10000: >= 10 ms (everything later), so that a
  // coarse view with an edge at 10 ms (GET_LATENCY) is exact.
  static constexpr std::size_t kBuckets = 10'001;

  void record_latency(int64_t ns) noexcept;   // RT-safe, writer only
  void record_cycle() noexcept;               // RT-safe, writer only
  void record_overruns(uint64_t n) noexcept;  // RT-safe, writer only
  void reset() noexcept;                      // not while the writer runs

  [[nodiscard]] LatencySummary summary() const noexcept;  // any thread; O(kBuckets)
  // Copies the bucket counts (index i: latency in [i, i+1) us; last: >= kBuckets-1 us).
  void copy_histogram(std::array<uint64_t, kBuckets>& out) const noexcept;
  // Adds the buckets up into a coarse histogram: `counts[j]` (set, not added to) is the
  // number of samples in [lower_ns[j], lower_ns[j+1]), the last one open. `lower_ns`
  // must start at 0 and increase strictly, with the same size as `counts`; an edge that
  // is not a multiple of kBucketNs counts a 1-us bucket where it starts, and edges
  // above 10 ms stay empty (the last bucket here is ">= 10 ms"). Returns the sum of
  // `counts` (0 and all counts 0 when the spans are empty or differ in size). Any
  // thread; RT-safe: no allocation, no lock, O(kBuckets) relaxed loads.
  uint64_t compress(std::span<const int64_t> lower_ns, std::span<uint64_t> counts) const noexcept;

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
