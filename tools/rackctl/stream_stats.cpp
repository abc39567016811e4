#include "stream_stats.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace rack::tools {

StreamStats::StreamStats(std::size_t window) : times_(std::max<std::size_t>(window, 2)), sizes_(times_.size()) {}

void StreamStats::add(int64_t arrival_ns, std::size_t bytes) {
  times_[next_] = arrival_ns;
  sizes_[next_] = bytes;
  next_ = (next_ + 1) % times_.size();
  count_ = std::min(count_ + 1, times_.size());
}

std::optional<StreamReport> StreamStats::report() const {
  if (count_ < 2) return std::nullopt;
  const std::size_t n = times_.size();
  const std::size_t first = (next_ + n - count_) % n;  // the oldest sample held
  StreamReport r;
  r.samples = count_;
  double sum = 0.0, sum_sq = 0.0;
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  double bytes_after_first = 0.0, bytes_all = 0.0;
  std::size_t size_lo = std::numeric_limits<std::size_t>::max(), size_hi = 0;
  for (std::size_t k = 0; k < count_; ++k) {
    const std::size_t i = (first + k) % n;
    const auto size = sizes_[i];
    bytes_all += static_cast<double>(size);
    size_lo = std::min(size_lo, size);
    size_hi = std::max(size_hi, size);
    if (k == 0) continue;
    bytes_after_first += static_cast<double>(size);
    const double period = static_cast<double>(times_[i] - times_[(i + n - 1) % n]) * 1e-9;
    sum += period;
    sum_sq += period * period;
    lo = std::min(lo, period);
    hi = std::max(hi, period);
  }
  const auto periods = static_cast<double>(count_ - 1);
  r.period_mean_s = sum / periods;
  r.period_std_s = std::sqrt(std::max(0.0, sum_sq / periods - r.period_mean_s * r.period_mean_s));
  r.period_min_s = lo;
  r.period_max_s = hi;
  // sum is the span from the first arrival to the last; 0 when all came at once.
  r.rate_hz = sum > 0.0 ? periods / sum : 0.0;
  r.bytes_per_s = sum > 0.0 ? bytes_after_first / sum : 0.0;
  r.size_mean_bytes = bytes_all / static_cast<double>(count_);
  r.size_min_bytes = size_lo;
  r.size_max_bytes = size_hi;
  return r;
}

namespace {
std::string three_digits(double v, const char* unit) {
  char buf[48];
  const double a = std::fabs(v);
  // Decided on the rounded value, so that 9.9997 prints as "10.0", not "10.00".
  const int decimals = a >= 99.95 ? 0 : a >= 9.995 ? 1 : 2;
  std::snprintf(buf, sizeof buf, "%.*f %s", decimals, v, unit);
  return buf;
}
}  // namespace

std::string seconds_text(double s) {
  const double a = std::fabs(s);
  if (a >= 0.9995) return three_digits(s, "s");  // not "1000 ms"
  if (a >= 0.9995e-3) return three_digits(s * 1e3, "ms");
  if (a >= 0.9995e-6 || a == 0.0) return three_digits(s * 1e6, "us");
  return three_digits(s * 1e9, "ns");
}

std::string hertz_text(double hz) {
  if (std::fabs(hz) >= 999.5) return three_digits(hz / 1e3, "kHz");
  return three_digits(hz, "Hz");
}

std::string bytes_text(double bytes) {
  const double a = std::fabs(bytes);
  constexpr double kKi = 1024.0;
  if (a >= 999.5 * kKi * kKi) return three_digits(bytes / (kKi * kKi * kKi), "GiB");
  if (a >= 999.5 * kKi) return three_digits(bytes / (kKi * kKi), "MiB");
  if (a >= 999.5) return three_digits(bytes / kKi, "KiB");
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0f B", bytes);
  return buf;
}

bool in_open_bucket(int64_t p_ns, int64_t max_ns, int64_t open_from_ns) { return p_ns > open_from_ns && p_ns < max_ns; }

std::string percentile_text(int64_t p_ns, int64_t max_ns, int64_t open_from_ns) {
  if (in_open_bucket(p_ns, max_ns, open_from_ns)) {
    return ">= " + seconds_text(static_cast<double>(open_from_ns) * 1e-9);
  }
  return seconds_text(static_cast<double>(p_ns) * 1e-9);
}

std::string hz_line(const StreamReport& r) {
  return "rate " + hertz_text(r.rate_hz) + "  period min " + seconds_text(r.period_min_s) + ", max " +
         seconds_text(r.period_max_s) + ", mean " + seconds_text(r.period_mean_s) + ", std " +
         seconds_text(r.period_std_s) + "  (window " + std::to_string(r.samples) + " samples)";
}

std::string bw_line(const StreamReport& r) {
  return "bandwidth " + bytes_text(r.bytes_per_s) + "/s  message mean " + bytes_text(r.size_mean_bytes) + ", min " +
         bytes_text(static_cast<double>(r.size_min_bytes)) + ", max " +
         bytes_text(static_cast<double>(r.size_max_bytes)) + "  (window " + std::to_string(r.samples) + " samples)";
}

std::string stream_json(const StreamReport& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "{\"samples\":%zu,\"rate_hz\":%.6g,\"period_s\":{\"min\":%.6g,\"max\":%.6g,\"mean\":%.6g,"
                "\"std\":%.6g},\"bytes_per_s\":%.6g,\"size_bytes\":{\"mean\":%.6g,\"min\":%zu,\"max\":%zu}}",
                r.samples, r.rate_hz, r.period_min_s, r.period_max_s, r.period_mean_s, r.period_std_s, r.bytes_per_s,
                r.size_mean_bytes, r.size_min_bytes, r.size_max_bytes);
  return buf;
}

}  // namespace rack::tools
