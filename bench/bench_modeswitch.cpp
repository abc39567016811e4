// Cost of mode-switch detection per cycle, each mode beside its reference in the
// same run (STYLE.md 11).
//
// A cycle is what a small data task does: a PI mutex lock/unlock (as publish() does),
// a 256-byte copy into a ring slot and a clock read. Variants, interleaved round by
// round on the same SCHED_FIFO thread settings and CPU:
//
//   reference       the cycle alone: no window, the thread not attached
//   off             window calls on a task whose mode is off (what every task pays)
//   warn            window on, detector armed (SUD selector, page-fault event,
//                   interposers), nothing reported: the normal cost
//   abort           the same with mode abort
//   +syscall ref    the cycle plus one getpid() system call, not attached
//   +syscall warn   the same in a warn window: getpid is on the allow-list but is
//                   trapped (SIGSYS round trip) because the cycle calls it directly
//
// With --rusage the detector runs with per-cycle getrusage (two system calls).
//
//   bench_modeswitch [--cycles N] [--rounds R] [--cpu C] [--priority P] [--rusage]
//                    [--json FILE]
//
// Needs root (SCHED_FIFO, mlockall). Prints a table; --json writes the same for
// bench/run (bench/results_md.py turns it into the mode-switch section of RESULTS.md).
#include <sys/syscall.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <functional>
#include <vector>

#include "bench_common.h"
#include "cycle_bench.h"
#include "rack/rt/clock.h"
#include "rack/rt/modeswitch.h"
#include "rack/rt/pi_mutex.h"

namespace {

using namespace rack::rt;
using rack::bench::Percentiles;
using rack::bench::percentiles_of;
using rack::bench::kernel_string;
namespace ms = rack::rt::modeswitch;

struct Variant {
  const char* name;
  bool attach;
  ms::Mode mode;
  bool window;
  bool syscall;
  std::vector<int64_t> samples;
};

struct Shared {
  PiMutex mutex;
  alignas(64) char ring[64][256] = {};
  char sample[256] = {};
};

__attribute__((noinline)) void cycle_body(Shared& s, unsigned i, bool syscall) {
  {
    PiLock lock(s.mutex);
    std::memcpy(s.ring[i % 64], s.sample, sizeof s.sample);
  }
  s.sample[i % 256] = static_cast<char>(monotonic_ns());
  if (syscall) (void)::syscall(SYS_getpid);  // direct, not through a framework call
}

void run_variant(Variant& v, Shared& shared, const rack::bench::CycleBenchOptions& o) {
  rack::bench::run_on_bench_thread(v.name, o, [&] {
    if (v.attach) ms::attach_current_thread(ms::TaskInfo{"bench", "bench", "Bench(0/0)", 0, v.mode});
    for (int k = 0; k < 200; ++k) cycle_body(shared, static_cast<unsigned>(k), v.syscall);  // warm-up
    for (int k = 0; k < o.cycles; ++k) {
      const int64_t t0 = monotonic_ns();
      if (v.window) ms::enter_cycle();
      cycle_body(shared, static_cast<unsigned>(k), v.syscall);
      if (v.window) (void)ms::leave_cycle();
      v.samples.push_back(monotonic_ns() - t0);
    }
    if (v.attach) ms::detach_current_thread();
  });
}

}  // namespace

int main(int argc, char** argv) {
  bool rusage = false;
  const rack::bench::CycleBenchOptions o = rack::bench::parse_cycle_bench_options(
      argc, argv, {20000, 10, 1, 80, {}, {}},
      "bench_modeswitch [--cycles N] [--rounds R] [--cpu C] [--priority P] [--rusage] [--json FILE]",
      [&](const std::string& option, const std::function<int()>&) {
        if (option != "--rusage") return false;
        rusage = true;
        return true;
      });
  const int cycles = o.cycles, rounds = o.rounds, cpu = o.cpu, priority = o.priority;
  const std::string& json = o.json;
  const auto mem = rack::bench::apply_cycle_bench_memory();
  ms::Config config;
  config.program = "bench_modeswitch";
  config.crash_dir = "/tmp/rack-bench-modeswitch";
  config.rusage = rusage;
  const auto started = ms::start(config);
  std::fprintf(stderr, "%s\n%s\n", mem.describe().c_str(), started.describe().c_str());

  std::vector<Variant> variants = {
      {"reference", false, ms::Mode::kWarn, false, false, {}},
      {"off", true, ms::Mode::kOff, true, false, {}},
      {"warn", true, ms::Mode::kWarn, true, false, {}},
      {"abort", true, ms::Mode::kAbort, true, false, {}},
      {"+syscall ref", false, ms::Mode::kWarn, false, true, {}},
      {"+syscall warn", true, ms::Mode::kWarn, true, true, {}},
  };
  for (auto& v : variants) v.samples.reserve(static_cast<std::size_t>(cycles) * static_cast<std::size_t>(rounds));
  Shared shared;
  for (int r = 0; r < rounds; ++r) {
    for (auto& v : variants) run_variant(v, shared, o);
  }
  const auto counts = ms::counters();
  ms::stop();

  std::printf("mode-switch detection cost per cycle%s: %d rounds x %d cycles per variant, CPU %d, SCHED_FIFO %d\n",
              rusage ? " (with per-cycle getrusage)" : "", rounds, cycles, cpu, priority);
  std::printf("kernel %s\n", kernel_string().c_str());
  std::printf("%-14s %9s %9s %9s %9s   %-22s %s\n", "variant", "p50 ns", "p99 ns", "p99.9 ns", "max ns",
              "minus ref p50 / p99", "ratio to ref p50 / p99");
  Percentiles ref{}, ref_sys{};
  std::string j = "{\"machine\": " + rack::bench::json_machine() + ", \"cycles\": " + std::to_string(cycles) +
                  ", \"rounds\": " + std::to_string(rounds) + ", \"cpu\": " + std::to_string(cpu) +
                  ", \"priority\": " + std::to_string(priority) + ", \"rusage\": " + (rusage ? "true" : "false") +
                  ", \"variants\": [";
  bool first = true;
  for (auto& v : variants) {
    const Percentiles p = percentiles_of(v.samples);
    j += std::string(first ? "" : ", ") + "{\"name\": \"" + v.name + "\", \"reference\": \"" +
         (v.syscall ? "+syscall ref" : "reference") + "\", \"latency\": " + rack::bench::json_percentiles(p) + "}";
    first = false;
    const bool sys = v.syscall;
    if (std::string(v.name) == "reference") ref = p;
    if (std::string(v.name) == "+syscall ref") ref_sys = p;
    const Percentiles& base = sys ? ref_sys : ref;
    char diff[64];
    std::snprintf(diff, sizeof diff, "%+.0f / %+.0f ns", p.p50_ns - base.p50_ns, p.p99_ns - base.p99_ns);
    std::printf("%-14s %9.0f %9.0f %9.0f %9.0f   %-22s %.2fx / %.2fx\n", v.name, p.p50_ns, p.p99_ns, p.p999_ns,
                p.max_ns, diff, p.p50_ns / base.p50_ns, p.p99_ns / base.p99_ns);
  }
  std::printf(
      "reports recorded during the run: %llu (expected 0: getpid is on the allow-list, trapped but not reported)\n",
      static_cast<unsigned long long>(counts.reports));
  j += "], \"reports\": " + std::to_string(counts.reports) + ", \"memory\": \"" +
       rack::bench::json_escape(mem.describe()) + "\", \"detector\": \"" +
       rack::bench::json_escape(started.describe()) + "\"}\n";
  if (!json.empty() && !rack::bench::write_file(json, j)) {
    std::fprintf(stderr, "bench_modeswitch: cannot write %s\n", json.c_str());
    return 1;
  }
  return 0;
}
