// The set-up that the per-cycle cost benchmarks share (bench_trace, bench_modeswitch):
// their command line (--cycles, --rounds, --cpu, --priority, --json, -h, plus options
// of their own), the memory policy of a real-time process, and one SCHED_FIFO thread
// per run of a variant, started and joined on the same settings each round.
//
// Not RT code: everything here runs around the measured loops, not in them.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <utility>

#include "rack/rt/memory.h"
#include "rack/rt/thread.h"

namespace rack::bench {

struct CycleBenchOptions {
  int cycles = 20000;
  int rounds = 10;
  int cpu = 1;
  int priority = 80;
  std::string json;          // --json FILE: bench/run's result file ("" : none)
  std::string command_line;  // argv joined, for the result file
};

// A benchmark's own option: `option` is argv[i]; `next_int()` takes the value after it
// (exits 2 when there is none). Returns false when it is not an option of the benchmark.
using ExtraOption = std::function<bool(const std::string& option, const std::function<int()>& next_int)>;

// Parses the shared options over `defaults` and the benchmark's own (`extra`). -h prints
// `usage` and exits 0; an unknown option or a missing value exits 2 with a message.
inline CycleBenchOptions parse_cycle_bench_options(int argc, char** argv, CycleBenchOptions defaults, const char* usage,
                                                   const ExtraOption& extra = {}) {
  CycleBenchOptions o = std::move(defaults);
  for (int i = 0; i < argc; ++i) {
    if (i > 0) o.command_line += ' ';
    o.command_line += argv[i];
  }
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const std::function<int()> next = [&] {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::atoi(argv[++i]);
    };
    if (a == "--cycles") o.cycles = next();
    else if (a == "--rounds") o.rounds = next();
    else if (a == "--cpu") o.cpu = next();
    else if (a == "--priority") o.priority = next();
    else if (a == "--json" && i + 1 < argc) o.json = argv[++i];
    else if (a == "-h" || a == "--help") {
      std::puts(usage);
      std::exit(0);
    } else if (!extra || !extra(a, next)) {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      std::exit(2);
    }
  }
  return o;
}

// mlockall and a prefaulted heap, as rackd does before its tasks start; the result's
// describe() is printed to stderr by the caller.
inline rt::MemoryPolicyResult apply_cycle_bench_memory() { return rt::apply_memory_policy(64u << 20); }

// Runs `body` once on a new thread named bench:<variant> at the options' SCHED_FIFO
// priority on their CPU (256 KiB stack, no fallback to normal scheduling), and waits.
inline void run_on_bench_thread(const std::string& variant, const CycleBenchOptions& o, std::function<void()> body) {
  rt::Thread t;
  t.start({std::string("bench:") + variant, o.priority, o.cpu, 256 * 1024}, std::move(body), false);
  t.join();
}

}  // namespace rack::bench
