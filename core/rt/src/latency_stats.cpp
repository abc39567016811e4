#include "rack/rt/latency_stats.h"

#include <algorithm>

namespace rack::rt {

namespace {
// Single-writer increment: load + store, no locked RMW instruction on the RT path.
template <typename T>
void bump(std::atomic<T>& a, T by) noexcept {
  a.store(a.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
}
}  // namespace

void LatencyStats::record_latency(int64_t ns) noexcept {
  if (ns < 0) ns = 0;
  auto idx = static_cast<std::size_t>(ns / kBucketNs);
  if (idx >= kBuckets) idx = kBuckets - 1;
  bump(buckets_[idx], uint64_t{1});
  bump(samples_, uint64_t{1});
  bump(sum_ns_, ns);
  if (ns < min_ns_.load(std::memory_order_relaxed)) min_ns_.store(ns, std::memory_order_relaxed);
  if (ns > max_ns_.load(std::memory_order_relaxed)) max_ns_.store(ns, std::memory_order_relaxed);
}

void LatencyStats::record_cycle() noexcept { bump(cycles_, uint64_t{1}); }
void LatencyStats::record_overruns(uint64_t n) noexcept { bump(overruns_, n); }

void LatencyStats::reset() noexcept {
  for (auto& b : buckets_) b.store(0, std::memory_order_relaxed);
  cycles_.store(0, std::memory_order_relaxed);
  overruns_.store(0, std::memory_order_relaxed);
  samples_.store(0, std::memory_order_relaxed);
  sum_ns_.store(0, std::memory_order_relaxed);
  min_ns_.store(INT64_MAX, std::memory_order_relaxed);
  max_ns_.store(0, std::memory_order_relaxed);
}

void LatencyStats::copy_histogram(std::array<uint64_t, kBuckets>& out) const noexcept {
  for (std::size_t i = 0; i < kBuckets; ++i) out[i] = buckets_[i].load(std::memory_order_relaxed);
}

uint64_t LatencyStats::compress(std::span<const int64_t> lower_ns, std::span<uint64_t> counts) const noexcept {
  for (auto& c : counts) c = 0;
  if (lower_ns.empty() || lower_ns.size() != counts.size()) return 0;
  // The first 1-us bucket at or above an edge (fine bucket i starts at i us).
  const auto first_at = [](int64_t edge_ns) -> std::size_t {
    if (edge_ns <= 0) return 0;
    const auto i = static_cast<std::size_t>((edge_ns + kBucketNs - 1) / kBucketNs);
    return i < kBuckets ? i : kBuckets;
  };
  // Coarse bucket j sums the fine buckets from its edge to the next one's: a tight
  // loop of loads per bucket (one pass with a branch per fine bucket took 3x as long,
  // bench_latency_reply).
  uint64_t total = 0;
  for (std::size_t j = 0; j < lower_ns.size(); ++j) {
    const std::size_t begin = j == 0 ? 0 : first_at(lower_ns[j]);
    const std::size_t end = j + 1 < lower_ns.size() ? first_at(lower_ns[j + 1]) : kBuckets;
    uint64_t sum = 0;
    for (std::size_t i = begin; i < end; ++i) sum += buckets_[i].load(std::memory_order_relaxed);
    counts[j] = sum;
    total += sum;
  }
  return total;
}

LatencySummary LatencyStats::summary() const noexcept {
  LatencySummary s;
  s.cycles = cycles_.load(std::memory_order_relaxed);
  s.overruns = overruns_.load(std::memory_order_relaxed);
  uint64_t total = 0;
  for (const auto& b : buckets_) total += b.load(std::memory_order_relaxed);
  s.samples = total;
  if (total == 0) return s;
  s.min_ns = min_ns_.load(std::memory_order_relaxed);
  s.max_ns = max_ns_.load(std::memory_order_relaxed);
  s.mean_ns = sum_ns_.load(std::memory_order_relaxed) / static_cast<int64_t>(total);
  // Percentile p: the upper edge of the bucket where the cumulative count reaches p,
  // capped by the exact maximum.
  const auto rank = [total](double p) {
    auto r = static_cast<uint64_t>(p * static_cast<double>(total));
    return r == 0 ? uint64_t{1} : r;
  };
  const uint64_t r50 = rank(0.50), r99 = rank(0.99), r999 = rank(0.999);
  uint64_t cum = 0;
  bool got50 = false, got99 = false;
  for (std::size_t i = 0; i < kBuckets; ++i) {
    cum += buckets_[i].load(std::memory_order_relaxed);
    const int64_t edge = std::min(static_cast<int64_t>(i + 1) * kBucketNs, s.max_ns);
    if (!got50 && cum >= r50) {
      s.p50_ns = edge;
      got50 = true;
    }
    if (!got99 && cum >= r99) {
      s.p99_ns = edge;
      got99 = true;
    }
    if (cum >= r999) {
      s.p999_ns = edge;
      break;
    }
  }
  return s;
}

}  // namespace rack::rt
