// rackctl hz / bw: the rate and bandwidth of a data stream over a rolling window of
// its last samples (as ros2 topic hz/bw): rate, min/max/mean/std of the period between
// arrivals, bytes per second and message sizes. Arrival times are rackctl's own
// (monotonic clock at receipt), so the figures include the network's jitter.
//
// Not RT code (allocates the window once; a plain single-threaded object).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rack::tools {

struct StreamReport {
  std::size_t samples = 0;    // in the window
  double rate_hz = 0.0;       // (samples - 1) / time from the first to the last
  double period_min_s = 0.0;  // between consecutive arrivals
  double period_max_s = 0.0;
  double period_mean_s = 0.0;
  double period_std_s = 0.0;  // population standard deviation
  double bytes_per_s = 0.0;   // bytes of every sample but the first / time span
  double size_mean_bytes = 0.0;
  std::size_t size_min_bytes = 0;
  std::size_t size_max_bytes = 0;
};

class StreamStats {
 public:
  explicit StreamStats(std::size_t window);  // window >= 2 samples
  void add(int64_t arrival_ns, std::size_t bytes);
  // nullopt until two samples arrived (no period yet).
  [[nodiscard]] std::optional<StreamReport> report() const;
  [[nodiscard]] std::size_t window() const { return times_.size(); }

 private:
  std::vector<int64_t> times_;
  std::vector<std::size_t> sizes_;
  std::size_t next_ = 0;   // slot of the next sample
  std::size_t count_ = 0;  // samples held (<= window)
};

// Numbers for people: 3 significant digits and a unit that keeps them readable.
[[nodiscard]] std::string seconds_text(double s);    // "98.7 ms", "1.50 s", "12.0 us"
[[nodiscard]] std::string hertz_text(double hz);     // "10.0 Hz", "1.20 kHz"
[[nodiscard]] std::string bytes_text(double bytes);  // "812 B", "1.25 KiB", "3.40 MiB"

// A latency percentile of the executor's histogram for people: "37.0 us", or
// ">= 10 ms" when it lies in the open last bucket that starts at `open_from_ns`
// (such a percentile comes back as that bucket's upper edge, below the exact max).
[[nodiscard]] bool in_open_bucket(int64_t p_ns, int64_t max_ns, int64_t open_from_ns);
[[nodiscard]] std::string percentile_text(int64_t p_ns, int64_t max_ns, int64_t open_from_ns);

// One line each, as rackctl hz and bw print them.
[[nodiscard]] std::string hz_line(const StreamReport& r);
[[nodiscard]] std::string bw_line(const StreamReport& r);
// One JSON object (raw SI values, plus the window).
[[nodiscard]] std::string stream_json(const StreamReport& r);

}  // namespace rack::tools
