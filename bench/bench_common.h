// Helpers shared by the side-by-side benchmarks (STYLE.md 11): percentiles from raw
// samples and from 1-us histograms (one definition for both sides of a comparison),
// a PM QoS hold, the machine description, and a tiny JSON writer.
//
// Not RT code: everything here runs before or after the measured loops.
#pragma once

#include <fcntl.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace rack::bench {

// Percentiles in ns. Nearest-rank definition: p-th percentile is the smallest value
// with at least ceil(p * n) samples at or below it.
struct Percentiles {
  uint64_t samples = 0;
  double min_ns = 0, p50_ns = 0, p90_ns = 0, p99_ns = 0, p999_ns = 0, max_ns = 0, mean_ns = 0;
};

inline uint64_t nearest_rank(double p, uint64_t n) {
  const auto r = static_cast<uint64_t>(std::ceil(p * static_cast<double>(n)));
  return r == 0 ? 1 : (r > n ? n : r);
}

// From raw samples (ns). Sorts `v`.
inline Percentiles percentiles_of(std::vector<int64_t>& v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  const uint64_t n = v.size();
  const auto at = [&](double q) { return static_cast<double>(v[nearest_rank(q, n) - 1]); };
  p.samples = n;
  p.min_ns = static_cast<double>(v.front());
  p.max_ns = static_cast<double>(v.back());
  p.p50_ns = at(0.50);
  p.p90_ns = at(0.90);
  p.p99_ns = at(0.99);
  p.p999_ns = at(0.999);
  long double sum = 0;
  for (int64_t x : v) sum += static_cast<long double>(x);
  p.mean_ns = static_cast<double>(sum / static_cast<long double>(n));
  return p;
}

// From a histogram of 1-us buckets (bucket i holds latencies in [i, i+1) us, which
// is both cyclictest's and rack::rt::LatencyStats' definition). A percentile is
// reported as its bucket's lower edge in ns (i.e. truncated to whole us, as
// cyclictest prints); `exact_max_ns` replaces the histogram's max when known.
inline Percentiles percentiles_of_histogram(const std::vector<uint64_t>& buckets, double exact_max_ns) {
  Percentiles p;
  uint64_t n = 0;
  long double sum = 0;
  for (std::size_t i = 0; i < buckets.size(); ++i) {
    n += buckets[i];
    sum += static_cast<long double>(buckets[i]) * (static_cast<long double>(i) + 0.5L) * 1000.0L;
  }
  if (n == 0) return p;
  p.samples = n;
  const uint64_t r50 = nearest_rank(0.50, n), r90 = nearest_rank(0.90, n), r99 = nearest_rank(0.99, n),
                 r999 = nearest_rank(0.999, n);
  uint64_t cum = 0;
  bool have_min = false;
  for (std::size_t i = 0; i < buckets.size(); ++i) {
    if (buckets[i] == 0) continue;
    const double edge = static_cast<double>(i) * 1000.0;
    if (!have_min) {
      p.min_ns = edge;
      have_min = true;
    }
    const uint64_t before = cum;
    cum += buckets[i];
    if (before < r50 && cum >= r50) p.p50_ns = edge;
    if (before < r90 && cum >= r90) p.p90_ns = edge;
    if (before < r99 && cum >= r99) p.p99_ns = edge;
    if (before < r999 && cum >= r999) p.p999_ns = edge;
    p.max_ns = edge;
  }
  if (exact_max_ns > 0) p.max_ns = exact_max_ns;
  p.mean_ns = static_cast<double>(sum / static_cast<long double>(n));
  return p;
}

// Holds /dev/cpu_dma_latency at `us` while alive (what cyclictest does by default:
// it keeps the CPUs out of deep idle states, which matters a lot for wake-up latency
// in a VM with cpuidle-haltpoll). The kernel applies the minimum of all holders.
class PmQosHold {
 public:
  explicit PmQosHold(int32_t us) {
    fd_ = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
    if (fd_ >= 0 && ::write(fd_, &us, sizeof us) != static_cast<ssize_t>(sizeof us)) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~PmQosHold() {
    if (fd_ >= 0) ::close(fd_);
  }
  PmQosHold(const PmQosHold&) = delete;
  PmQosHold& operator=(const PmQosHold&) = delete;
  [[nodiscard]] bool active() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

inline std::string read_first_line(const char* path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

inline std::string kernel_string() {
  utsname u{};
  if (uname(&u) != 0) return "?";
  return std::string(u.sysname) + " " + u.release + " " + u.version + " " + u.machine;
}

inline bool kernel_is_preempt_rt() { return read_first_line("/sys/kernel/realtime") == "1"; }

inline std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      return colon == std::string::npos ? line : line.substr(colon + 2);
    }
  }
  return "?";
}

inline std::string json_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out;
}

inline std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

inline std::string json_percentiles(const Percentiles& p) {
  std::ostringstream o;
  o << "{\"samples\": " << p.samples << ", \"min_ns\": " << json_number(p.min_ns)
    << ", \"p50_ns\": " << json_number(p.p50_ns) << ", \"p90_ns\": " << json_number(p.p90_ns)
    << ", \"p99_ns\": " << json_number(p.p99_ns) << ", \"p999_ns\": " << json_number(p.p999_ns)
    << ", \"max_ns\": " << json_number(p.max_ns) << ", \"mean_ns\": " << json_number(p.mean_ns) << "}";
  return o.str();
}

// The machine block every result file carries.
inline std::string json_machine() {
  std::ostringstream o;
  o << "{\"kernel\": \"" << json_escape(kernel_string())
    << "\", \"preempt_rt\": " << (kernel_is_preempt_rt() ? "true" : "false") << ", \"cpu_model\": \""
    << json_escape(cpu_model()) << "\", \"online_cpus\": " << sysconf(_SC_NPROCESSORS_ONLN)
    << ", \"cpuidle_driver\": \"" << json_escape(read_first_line("/sys/devices/system/cpu/cpuidle/current_driver"))
    << "\"}";
  return o.str();
}

inline bool write_file(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  return static_cast<bool>(out);
}

inline double us(double ns) { return ns / 1000.0; }

}  // namespace rack::bench
