// Cost of the virtual-clock override (issue 22, item 4) in a task's cycle, beside the
// clock read as it was before, in the same run (STYLE.md 11).
//
// rt::monotonic_ns() now checks for an installed rt::VirtualClock (a relaxed pointer
// load and a branch) before reading CLOCK_MONOTONIC; rt::os_monotonic_ns() is the read
// without the check: the body monotonic_ns() had before, in the same library, called
// the same way. Variants, interleaved round by round (the order reversed every other
// round) on the same SCHED_FIFO thread settings and CPU:
//
//   before     the cycle reading the clock through os_monotonic_ns(): the old read
//   override   through monotonic_ns(), no virtual clock installed: what every task pays
//   virtual    through monotonic_ns() with a VirtualClock installed (tests only)
//
// A cycle is what a small periodic data task does with the clock: the 6 reads of the
// executor's periodic loop (wake-up latency, cycle start, loop() start and end, the
// renewal check, the overrun check) around one message hand-off (a 64-byte sample sent
// through the router into a mailbox and received). Each sample is one cycle timed by
// clock_gettime() directly (the same for every variant). Also the cost of one read:
// 1000 reads back to back, divided by 1000. Per round, each variant's p50 and p99 over
// the before variant's; printed: the median of the per-round ratios with their range.
//
//   bench_clock [--cycles N] [--rounds R] [--cpu C] [--priority P] [--json FILE]
//
// Target: the override costs nothing measurable in the cycle (median per-round p50
// ratio within 1.05x). Needs root (SCHED_FIFO, mlockall).
#include <algorithm>
#include <array>
#include <cstdio>
#include <ctime>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cycle_bench.h"
#include "cycle_bus.h"
#include "rack/rt/clock.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/message.h"
#include "rack/tims/router.h"

namespace {

using rack::bench::Percentiles;
using rack::bench::percentiles_of;
namespace rt = rack::rt;
namespace tims = rack::tims;

enum class Mode { kBefore, kOverride, kVirtual };
struct Variant {
  const char* name;
  Mode mode;
  std::vector<int64_t> pooled, pooled_read;
  std::vector<double> ratio_p50, ratio_p99, ratio_read;  // per round, to "before"
  Percentiles last, last_read;                           // this round's
};

using Bus = rack::bench::CycleBus;

// The measuring clock: the same inline read for every variant.
inline int64_t stopwatch() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return rt::from_timespec(ts);
}

using ClockFn = int64_t (*)() noexcept;

// Returns a value built from the reads so that none of them can be dropped.
template <ClockFn Now>
__attribute__((noinline)) int64_t cycle(Bus& bus, int64_t next, uint8_t seq) {
  int64_t sink = Now() - next;  // wake-up latency
  const int64_t cycle_start = Now();
  const int64_t renew_now = Now();  // renew_due_subscriptions(now)
  const int64_t started = Now();    // loop() starts
  const tims::ConstBuffer part{bus.sample.data(), bus.sample.size()};
  const auto h = tims::make_header(bus.sink.address(), bus.self, -6, 0, seq, static_cast<uint32_t>(bus.sample.size()));
  (void)bus.router.send(h, std::span<const tims::ConstBuffer>(&part, 1));
  (void)bus.sink.receive(bus.buffer, tims::Mailbox::kNonBlocking);
  const int64_t ended = Now();  // loop() ends
  const int64_t now = Now();    // the overrun check
  sink += (ended - started) + (now - cycle_start) + (renew_now & 1);
  return sink;
}

template <ClockFn Now>
__attribute__((noinline)) int64_t reads(int n) {
  int64_t sum = 0;
  for (int i = 0; i < n; ++i) sum += Now();
  return sum;
}

volatile int64_t g_sink = 0;  // keeps the results alive

template <ClockFn Now>
void measure(Variant& v, Bus& bus, const rack::bench::CycleBenchOptions& o, std::vector<int64_t>& samples,
             std::vector<int64_t>& read_samples) {
  int64_t keep = 0;
  for (int k = 0; k < 500; ++k) keep += cycle<Now>(bus, stopwatch(), static_cast<uint8_t>(k));  // warm-up
  for (int k = 0; k < o.cycles; ++k) {
    const int64_t t0 = stopwatch();
    keep += cycle<Now>(bus, t0, static_cast<uint8_t>(k));
    samples.push_back(stopwatch() - t0);
  }
  constexpr int kReads = 1000;
  for (int k = 0; k < o.cycles / 10; ++k) {
    const int64_t t0 = stopwatch();
    keep += reads<Now>(kReads);
    read_samples.push_back((stopwatch() - t0) / kReads);
  }
  g_sink = g_sink + keep;
  (void)v;
}

void run_variant(Variant& v, Bus& bus, const rack::bench::CycleBenchOptions& o) {
  std::vector<int64_t> samples, read_samples;
  samples.reserve(static_cast<std::size_t>(o.cycles));
  read_samples.reserve(static_cast<std::size_t>(o.cycles / 10));
  std::unique_ptr<rt::VirtualClock> clock;
  if (v.mode == Mode::kVirtual) clock = std::make_unique<rt::VirtualClock>();  // around this variant only
  rack::bench::run_on_bench_thread(v.name, o, [&] {
    if (v.mode == Mode::kBefore) measure<rt::os_monotonic_ns>(v, bus, o, samples, read_samples);
    else measure<rt::monotonic_ns>(v, bus, o, samples, read_samples);
  });
  clock.reset();
  v.pooled.insert(v.pooled.end(), samples.begin(), samples.end());
  v.pooled_read.insert(v.pooled_read.end(), read_samples.begin(), read_samples.end());
  v.last = percentiles_of(samples);
  v.last_read = percentiles_of(read_samples);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

std::string ratio_text(const std::vector<double>& r) {
  const auto [lo, hi] = std::minmax_element(r.begin(), r.end());
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3fx [%.3f, %.3f]", median(r), *lo, *hi);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  const rack::bench::CycleBenchOptions o = rack::bench::parse_cycle_bench_options(
      argc, argv, {20000, 7, 1, 80, {}, {}},
      "bench_clock [--cycles N] [--rounds R] [--cpu C] [--priority P] [--json FILE]");
  if (o.cycles < 100 || o.rounds < 1) {
    std::fprintf(stderr, "--cycles at least 100, --rounds at least 1\n");
    return 2;
  }
  const auto mem = rack::bench::apply_cycle_bench_memory();
  std::fprintf(stderr, "%s\n", mem.describe().c_str());
  Bus bus;
  std::vector<Variant> variants = {{"before", Mode::kBefore, {}, {}, {}, {}, {}, {}, {}},
                                   {"override", Mode::kOverride, {}, {}, {}, {}, {}, {}, {}},
                                   {"virtual", Mode::kVirtual, {}, {}, {}, {}, {}, {}, {}}};
  for (int r = 0; r < o.rounds; ++r) {
    std::vector<Variant*> order = {&variants[0], &variants[1], &variants[2]};
    if (r % 2 == 1) std::reverse(order.begin(), order.end());
    for (Variant* v : order) run_variant(*v, bus, o);
    for (auto& v : variants) {
      v.ratio_p50.push_back(v.last.p50_ns / variants[0].last.p50_ns);
      v.ratio_p99.push_back(v.last.p99_ns / variants[0].last.p99_ns);
      v.ratio_read.push_back(v.last_read.p50_ns / std::max(1.0, variants[0].last_read.p50_ns));
    }
  }
  std::printf("clock override cost: %d rounds x %d cycles per variant, CPU %d, SCHED_FIFO %d\n", o.rounds, o.cycles,
              o.cpu, o.priority);
  std::printf("kernel %s, %s\n", rack::bench::kernel_string().c_str(), rack::bench::cpu_model().c_str());
  std::printf("%-9s %7s %7s %7s %8s %8s  %-26s %-26s %8s  %s\n", "variant", "p50 ns", "p90 ns", "p99 ns", "p99.9 ns",
              "max ns", "cycle p50 ratio: median", "cycle p99 ratio: median", "read p50", "read ratio: median");
  std::vector<Percentiles> pooled, pooled_read;
  for (auto& v : variants) {
    pooled.push_back(percentiles_of(v.pooled));
    pooled_read.push_back(percentiles_of(v.pooled_read));
    const Percentiles& p = pooled.back();
    std::printf("%-9s %7.0f %7.0f %7.0f %8.0f %8.0f  %-26s %-26s %8.0f  %s\n", v.name, p.p50_ns, p.p90_ns, p.p99_ns,
                p.p999_ns, p.max_ns, ratio_text(v.ratio_p50).c_str(), ratio_text(v.ratio_p99).c_str(),
                pooled_read.back().p50_ns, ratio_text(v.ratio_read).c_str());
  }
  if (!o.json.empty()) {
    std::string md =
        "| variant | cycle p50 ns | p99 ns | p99.9 ns | per-round cycle p50 ratio: median [range] | per-round cycle "
        "p99 ratio: median [range] | one read p50 ns |\n|---|---|---|---|---|---|---|\n";
    for (std::size_t k = 0; k < variants.size(); ++k) {
      const Percentiles& p = pooled[k];
      char row[512];
      std::snprintf(row, sizeof row, "| %s | %.0f | %.0f | %.0f | %s | %s | %.0f |\n", variants[k].name, p.p50_ns,
                    p.p99_ns, p.p999_ns, ratio_text(variants[k].ratio_p50).c_str(),
                    ratio_text(variants[k].ratio_p99).c_str(), pooled_read[k].p50_ns);
      md += row;
    }
    char note[256];
    std::snprintf(note, sizeof note,
                  "Override (not installed): median per-round cycle p50 ratio %.3fx (target: within 1.05x: %s).",
                  median(variants[1].ratio_p50), median(variants[1].ratio_p50) <= 1.05 ? "met" : "MISSED");
    const std::string about =
        "A cycle is a small periodic data task's use of the clock (6 reads) around a 64-byte message hand-off; "
        "before: the reads without the virtual-clock check (rt::os_monotonic_ns, the old body); override: "
        "rt::monotonic_ns with no virtual clock installed (every task of rackd); virtual: one installed (tests). " +
        std::to_string(o.rounds) + " rounds x " + std::to_string(o.cycles) +
        " cycles per variant, interleaved, SCHED_FIFO " + std::to_string(o.priority) + " on CPU " +
        std::to_string(o.cpu) + ".";
    std::string j = "{\n  \"benchmark\": \"clock\",\n  \"command\": \"";
    j += rack::bench::json_escape(o.command_line);
    j += "\",\n  \"machine\": ";
    j += rack::bench::json_machine();
    j += ",\n  \"title\": \"bench_clock: the virtual-clock override's cost per cycle vs the clock read before\"";
    j += ",\n  \"about\": \"" + rack::bench::json_escape(about) + "\"";
    j += ",\n  \"markdown\": \"" + rack::bench::json_escape(md) + "\"";
    j +=
        ",\n  \"comparisons\": [\n    {\"name\": \"override (not installed) vs before\", \"rack_label\": \"override\", "
        "\"reference_label\": \"before\", \"rack\": ";
    j += rack::bench::json_percentiles(pooled[1]);
    j += ", \"reference\": ";
    j += rack::bench::json_percentiles(pooled[0]);
    j += ", \"metric\": \"p50_ns\", \"target_ratio\": 1.05}\n  ],\n  \"notes\": [\"";
    j += rack::bench::json_escape(note);
    j += "\"]\n}\n";
    if (!rack::bench::write_file(o.json, j)) {
      std::fprintf(stderr, "bench_clock: cannot write %s\n", o.json.c_str());
      return 1;
    }
  }
  return 0;
}
