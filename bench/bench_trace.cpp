// Cost of the task timeline per cycle (issue 20, item 4), beside the same cycle
// without it, in the same run (STYLE.md 11).
//
// A cycle is what a small data task does with the trace hooks of rackd's executor:
// the wake-up record (5 events a cycle in all), cycle start and end (record_at with the clock reads the
// executor makes anyway), and one message hand-off: a 64-byte sample sent through the
// router into a mailbox (the send hook) and received from it (the receive hook).
// Variants, interleaved round by round on the same SCHED_FIFO thread settings and CPU:
//
//   reference   no trace ring bound to the thread: the task without a timeline
//   off         a ring bound and switched off: what every task pays in rackd
//   on          the ring switched on, drained every 2 ms by a normal thread on
//               another CPU (rackd's trace thread drains every 10 ms)
//
// Each sample is the time of one cycle (two clock reads around it). Per round, the
// ratio of each variant's p50 and p99 to the reference's; printed: the median of the
// per-round ratios with their range, and the pooled percentiles.
//
//   bench_trace [--cycles N] [--rounds R] [--cpu C] [--drain-cpu C] [--priority P] [--json FILE]
//
// --json writes bench/run's generic form (results_md.py renders it): the off and on
// variants against the reference, and a table in ns. Targets (issue 20): off costs
// nothing measurable (median per-round p50 ratio within 1.05x), on under 1 us per cycle.
//
// Needs root (SCHED_FIFO, mlockall).
#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <pthread.h>
#include <sched.h>

#include "bench_common.h"
#include "cycle_bench.h"
#include "cycle_bus.h"
#include "rack/rt/clock.h"
#include "rack/rt/trace.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/message.h"
#include "rack/tims/router.h"

namespace {

using namespace rack::rt;
using rack::bench::Percentiles;
using rack::bench::percentiles_of;
namespace tims = rack::tims;

enum class Mode { kReference, kOff, kOn };
struct Variant {
  const char* name;
  Mode mode;
  std::vector<int64_t> pooled;
  std::vector<double> ratio_p50, ratio_p99;  // per round, to the reference
  Percentiles last;                          // this round's
};

using Bus = rack::bench::CycleBus;

__attribute__((noinline)) int64_t cycle(Bus& bus, int64_t due, uint8_t seq) {
  const int64_t woke = monotonic_ns();
  trace::record(trace::Kind::kWake, due);
  trace::record_at(woke, trace::Kind::kCycleStart);
  const tims::ConstBuffer part{bus.sample.data(), bus.sample.size()};
  const auto h = tims::make_header(bus.sink.address(), bus.self, -6, 0, seq, static_cast<uint32_t>(bus.sample.size()));
  (void)bus.router.send(h, std::span<const tims::ConstBuffer>(&part, 1));
  (void)bus.sink.receive(bus.buffer, tims::Mailbox::kNonBlocking);
  const int64_t ended = monotonic_ns();
  trace::record_at(ended, trace::Kind::kCycleEnd, 0);
  return ended - woke;
}

void run_variant(Variant& v, Bus& bus, trace::Ring& ring, const rack::bench::CycleBenchOptions& o, int drain_cpu) {
  std::vector<int64_t> samples;
  samples.reserve(static_cast<std::size_t>(o.cycles));
  std::atomic<bool> done{false};
  std::thread drainer;
  if (v.mode == Mode::kOn) {
    drainer = std::thread([&] {
      if (drain_cpu >= 0) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(static_cast<std::size_t>(drain_cpu), &set);
        (void)pthread_setaffinity_np(pthread_self(), sizeof set, &set);
      }
      std::vector<trace::Event> out(4096);
      while (!done.load(std::memory_order_acquire)) {
        while (ring.drain(out) > 0) {
        }
        sleep_for(2 * kNsPerMs);
      }
      while (ring.drain(out) > 0) {
      }
    });
  }
  rack::bench::run_on_bench_thread(v.name, o, [&] {
    trace::bind_thread_ring(v.mode == Mode::kReference ? nullptr : &ring);
    ring.set_enabled(v.mode == Mode::kOn);
    for (int k = 0; k < 500; ++k) (void)cycle(bus, monotonic_ns(), static_cast<uint8_t>(k));  // warm-up
    for (int k = 0; k < o.cycles; ++k) {
      samples.push_back(cycle(bus, monotonic_ns(), static_cast<uint8_t>(k)));
      // A task's cycles are spaced by its period: a pause every 512 cycles
      // (2560 events, within the ring's 4096) lets the drainer keep up, as it
      // does in rackd, so that "on" measures recording, not the drop path.
      if (k % 512 == 511) sleep_for(10 * kNsPerMs);
    }
    ring.set_enabled(false);
    trace::bind_thread_ring(nullptr);
  });
  done.store(true, std::memory_order_release);
  if (drainer.joinable()) drainer.join();
  v.pooled.insert(v.pooled.end(), samples.begin(), samples.end());
  v.last = percentiles_of(samples);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int drain_cpu = 0;
  const rack::bench::CycleBenchOptions o = rack::bench::parse_cycle_bench_options(
      argc, argv, {20000, 7, 1, 80, {}, {}},
      "bench_trace [--cycles N] [--rounds R] [--cpu C] [--drain-cpu C] [--priority P] [--json FILE]",
      [&](const std::string& option, const std::function<int()>& next_int) {
        if (option != "--drain-cpu") return false;
        drain_cpu = next_int();
        return true;
      });
  const int cycles = o.cycles, rounds = o.rounds, cpu = o.cpu, priority = o.priority;
  const std::string& json = o.json;
  const std::string& command_line = o.command_line;
  if (cycles < 100 || rounds < 1) {
    std::fprintf(stderr, "--cycles at least 100, --rounds at least 1\n");
    return 2;
  }
  const auto mem = rack::bench::apply_cycle_bench_memory();
  std::fprintf(stderr, "%s\n", mem.describe().c_str());
  Bus bus;
  trace::Ring ring(4096);
  std::vector<Variant> variants = {{"reference", Mode::kReference, {}, {}, {}, {}},
                                   {"off", Mode::kOff, {}, {}, {}, {}},
                                   {"on", Mode::kOn, {}, {}, {}, {}}};
  const uint64_t dropped_before = ring.dropped();
  for (int r = 0; r < rounds; ++r) {
    // Alternate the order too, so that no variant always follows the same one.
    std::vector<Variant*> order = {&variants[0], &variants[1], &variants[2]};
    if (r % 2 == 1) std::reverse(order.begin(), order.end());
    for (Variant* v : order) run_variant(*v, bus, ring, o, drain_cpu);
    for (auto& v : variants) {
      v.ratio_p50.push_back(v.last.p50_ns / variants[0].last.p50_ns);
      v.ratio_p99.push_back(v.last.p99_ns / variants[0].last.p99_ns);
    }
  }
  std::printf("trace cost per cycle: %d rounds x %d cycles per variant, CPU %d (drainer CPU %d), SCHED_FIFO %d\n",
              rounds, cycles, cpu, drain_cpu, priority);
  std::printf("kernel %s, %s\n", rack::bench::kernel_string().c_str(), rack::bench::cpu_model().c_str());
  std::printf("%-10s %8s %8s %8s %9s %9s  %-24s %-34s %s\n", "variant", "p50 ns", "p90 ns", "p99 ns", "p99.9 ns",
              "max ns", "minus ref p50 / p99 ns", "ratio p50: median [min, max]", "ratio p99: median [min, max]");
  Percentiles ref{};
  std::vector<Percentiles> pooled;
  for (auto& v : variants) {
    const Percentiles p = percentiles_of(v.pooled);
    pooled.push_back(p);
    if (v.mode == Mode::kReference) ref = p;
    const auto [p50_min, p50_max] = std::minmax_element(v.ratio_p50.begin(), v.ratio_p50.end());
    const auto [p99_min, p99_max] = std::minmax_element(v.ratio_p99.begin(), v.ratio_p99.end());
    std::printf(
        "%-10s %8.0f %8.0f %8.0f %9.0f %9.0f  %+8.0f / %+8.0f        %.3fx [%.3f, %.3f]              %.3fx [%.3f, %.3f]\n",
        v.name, p.p50_ns, p.p90_ns, p.p99_ns, p.p999_ns, p.max_ns, p.p50_ns - ref.p50_ns, p.p99_ns - ref.p99_ns,
        median(v.ratio_p50), *p50_min, *p50_max, median(v.ratio_p99), *p99_min, *p99_max);
  }
  const uint64_t dropped = ring.dropped() - dropped_before;
  std::printf("events recorded (on): %llu, dropped: %llu\n", static_cast<unsigned long long>(ring.pushed()),
              static_cast<unsigned long long>(dropped));
  if (!json.empty()) {
    std::string
        md = "| variant | p50 ns | p99 ns | p99.9 ns | minus reference p50 / p99 ns | per-round p50 ratio: median "
             "[range] | per-round p99 ratio: median [range] |\n|---|---|---|---|---|---|---|\n";
    for (std::size_t k = 0; k < variants.size(); ++k) {
      const Variant& v = variants[k];
      const Percentiles& p = pooled[k];
      const auto [p50_min, p50_max] = std::minmax_element(v.ratio_p50.begin(), v.ratio_p50.end());
      const auto [p99_min, p99_max] = std::minmax_element(v.ratio_p99.begin(), v.ratio_p99.end());
      char row[512];
      std::snprintf(row, sizeof row,
                    "| %s | %.0f | %.0f | %.0f | %+.0f / %+.0f | %.3fx [%.3f, %.3f] | %.3fx [%.3f, %.3f] |\n", v.name,
                    p.p50_ns, p.p99_ns, p.p999_ns, p.p50_ns - ref.p50_ns, p.p99_ns - ref.p99_ns, median(v.ratio_p50),
                    *p50_min, *p50_max, median(v.ratio_p99), *p99_min, *p99_max);
      md += row;
    }
    const double on_p50 = pooled[2].p50_ns - ref.p50_ns, on_p99 = pooled[2].p99_ns - ref.p99_ns;
    char note[512];
    std::snprintf(note, sizeof note,
                  "On: %+.0f ns at p50 and %+.0f ns at p99 per cycle against the reference (target: under 1000 ns: "
                  "%s); off: median per-round p50 ratio %.3fx (target: nothing measurable, within 1.05x: %s). "
                  "Events recorded while on: %llu, dropped: %llu.",
                  on_p50, on_p99, on_p99 < 1000.0 ? "met" : "MISSED", median(variants[1].ratio_p50),
                  median(variants[1].ratio_p50) <= 1.05 ? "met" : "MISSED",
                  static_cast<unsigned long long>(ring.pushed()), static_cast<unsigned long long>(dropped));
    const std::string about =
        "A cycle is what a small data task does with the executor's trace hooks (5 events: wake-up, cycle start "
        "and end, a 64-byte message sent through the router and received). reference: no ring bound; off: a ring "
        "bound and switched off (what every task of rackd pays); on: recording, drained by a normal thread on "
        "another CPU. " +
        std::to_string(rounds) + " rounds x " + std::to_string(cycles) +
        " cycles per variant, interleaved, SCHED_FIFO " + std::to_string(priority) + " on CPU " + std::to_string(cpu) +
        "; the time of each cycle, in ns below, us in the comparisons.";
    std::string j = "{\n  \"benchmark\": \"trace\",\n  \"command\": \"";
    j += rack::bench::json_escape(command_line);
    j += "\",\n  \"machine\": ";
    j += rack::bench::json_machine();
    j += ",\n  \"title\": \"bench_trace: the task timeline's cost per cycle, off and on, vs the cycle without it\"";
    j += ",\n  \"about\": \"";
    j += rack::bench::json_escape(about);
    j += "\",\n  \"markdown\": \"";
    j += rack::bench::json_escape(md);
    j += "\",\n  \"comparisons\": [\n";
    const char* names[2] = {"tracing off vs no ring", "tracing on vs no ring"};
    for (std::size_t k = 1; k <= 2; ++k) {
      if (k == 2) j += ",\n";
      j += "    {\"name\": \"";
      j += names[k - 1];
      j += "\", \"rack_label\": \"";
      j += variants[k].name;
      j += "\", \"reference_label\": \"no ring\", \"rack\": ";
      j += rack::bench::json_percentiles(pooled[k]);
      j += ", \"reference\": ";
      j += rack::bench::json_percentiles(ref);
      j += ", \"metric\": \"p50_ns\"";
      if (k == 1) j += ", \"target_ratio\": 1.05";
      j += "}";
    }
    j += "\n  ],\n  \"notes\": [\"";
    j += rack::bench::json_escape(note);
    j += "\"]\n}\n";
    if (!rack::bench::write_file(json, j)) {
      std::fprintf(stderr, "bench_trace: cannot write %s\n", json.c_str());
      return 1;
    }
  }
  return 0;
}
