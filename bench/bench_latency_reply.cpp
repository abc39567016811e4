// bench_latency_reply: what GET_LATENCY (the data task's wake-up latency histogram in
// 40 buckets, issue 10) costs a component, beside GET_STATS (the percentiles only),
// which every tool already asks for: the reference.
//
//   fill:  Component::fill_latency() vs Component::fill_stats() called directly on a
//          running Generator (the work its command task does per request: two passes
//          over the 10 001 1-us buckets vs one pass plus the listener count).
//   rpc:   tims::Endpoint::call(GET_LATENCY) vs call(GET_STATS) from a client thread
//          to the Generator's command task in one rack::Executor (lcm: false), with
//          the reply (728 vs 216 bytes) back into the client's mailbox.
//
// The two sides alternate in --rounds blocks so that a shared VM's drifts hit both
// alike; each call is timed with CLOCK_MONOTONIC. Prints percentiles of both and the
// ratios (GET_LATENCY / GET_STATS). Root for SCHED_FIFO (--priority 0: normal threads).
//
//   bench_latency_reply [--iterations N] [--rounds R] [--priority P] [--cpu C] [--gap-us G]
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_common.h"
#include "rack/components/builtin.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/core/registry.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/thread.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/mailbox.h"

namespace {

namespace rt = rack::rt;
namespace tims = rack::tims;
namespace wire = rack::wire;
using rack::bench::Percentiles;
using rack::bench::percentiles_of;

struct Options {
  uint64_t iterations = 20000;  // per side and part
  int rounds = 4;
  int priority = 80;
  int cpu = 0;
  int64_t gap_us = 50;  // the client sleeps between calls (not 100% RT load)
  std::string json;     // bench/run's generic form (bench/run's header)
};

void usage_exit(int code) {
  std::fprintf(code == 0 ? stdout : stderr,
               "usage: bench_latency_reply [--iterations N] [--rounds R] [--priority P] [--cpu C] [--gap-us G]\n"
               "  --iterations N  timed calls per side and part (default 20000)\n"
               "  --rounds R      alternate GET_LATENCY and GET_STATS in R blocks (default 4)\n"
               "  --priority P    SCHED_FIFO priority of the client and the command task (default 80; 0: normal)\n"
               "  --cpu C         CPU of the client, the command task and the data task (default 0)\n"
               "  --gap-us G      the client sleeps G us between calls (default 50)\n"
               "  --json FILE     also write the figures as JSON (bench/run's generic form)\n");
  std::exit(code);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string {
      if (i + 1 >= argc) usage_exit(2);
      return argv[++i];
    };
    try {
      if (a == "--iterations") o.iterations = std::stoull(next());
      else if (a == "--rounds") o.rounds = std::stoi(next());
      else if (a == "--priority") o.priority = std::stoi(next());
      else if (a == "--cpu") o.cpu = std::stoi(next());
      else if (a == "--gap-us") o.gap_us = std::stoll(next());
      else if (a == "--json") o.json = next();
      else if (a == "-h" || a == "--help") usage_exit(0);
      else usage_exit(2);
    } catch (const std::exception&) {
      usage_exit(2);
    }
  }
  if (o.iterations == 0 || o.rounds < 1 || o.priority < 0 || o.priority > 99) usage_exit(2);
  return o;
}

std::string host_text(const Options& o) {
  // The data task above the command task and the client (as on a robot: data 40,
  // command 30), so that the measurement shows whether GET_LATENCY disturbs it.
  const int data_priority = o.priority == 0 ? 0 : (o.priority < 99 ? o.priority + 1 : 99);
  return "host: bench-latency-reply\nsystem: 0\nhost_id: 0\nlcm: false\nheap_prefault_mib: 16\ncomponents:\n"
         "  - name: gen\n    class: Generator\n    instance: 0\n    autostart: true\n"
         "    command_task: {priority: " +
         std::to_string(o.priority) + ", cpu: " + std::to_string(o.cpu) +
         "}\n"
         // A running data task (1 kHz) so that the histogram fills while it is read.
         "    data_task: {priority: " +
         std::to_string(data_priority) + ", cpu: " + std::to_string(o.cpu) + ", period_ms: 1}\n";
}

void print_row(const char* name, const Percentiles& p) {
  std::printf("  %-22s %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f\n", name, p.min_ns / 1e3, p.p50_ns / 1e3, p.p99_ns / 1e3,
              p.p999_ns / 1e3, p.max_ns / 1e3, p.mean_ns / 1e3);
}

void print_part(const char* title, std::vector<int64_t>& latency, std::vector<int64_t>& stats, uint64_t failures) {
  const Percentiles a = percentiles_of(latency);
  const Percentiles b = percentiles_of(stats);
  std::printf("%s (us; %llu calls each, %llu failed)\n", title, static_cast<unsigned long long>(a.samples),
              static_cast<unsigned long long>(failures));
  std::printf("  %-22s %9s %9s %9s %9s %9s %9s\n", "", "min", "p50", "p99", "p99.9", "max", "mean");
  print_row("GET_LATENCY", a);
  print_row("GET_STATS (reference)", b);
  std::printf("  %-22s %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f\n", "ratio", a.min_ns / b.min_ns, a.p50_ns / b.p50_ns,
              a.p99_ns / b.p99_ns, a.p999_ns / b.p999_ns, a.max_ns / b.max_ns, a.mean_ns / b.mean_ns);
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  try {
    const rt::RtCapabilities caps = rt::probe_capabilities();
    rack::ComponentRegistry registry;
    rack::components::register_builtin(registry);
    auto loaded = rack::load_host_text(host_text(o), "bench_latency_reply.yaml", registry, caps);
    if (!loaded.errors.empty()) throw std::runtime_error("host text rejected: " + loaded.errors.front().str());
    rack::ExecutorOptions eo;
    eo.allow_rt_fallback = o.priority == 0;
    eo.log = [](const std::string&) {};
    rack::Executor executor(std::move(loaded.host), eo);
    executor.start();
    rack::Component* gen = executor.find("gen");
    if (gen == nullptr) throw std::runtime_error("component 'gen' not found");
    tims::Mailbox mailbox(tims::Address::make(0, tims::classes::kTool, 1, 0), 8, 4096);
    executor.router().add(mailbox);
    tims::Endpoint endpoint(executor.router(), mailbox, static_cast<uint8_t>(o.priority));
    rt::sleep_for(500 * rt::kNsPerMs);  // some samples in the histogram

    std::printf("bench_latency_reply: kernel %s (%s), %s; priority %d, cpu %d, %d rounds, gap %lld us\n",
                rack::bench::kernel_string().c_str(),
                rack::bench::kernel_is_preempt_rt() ? "PREEMPT_RT" : "not PREEMPT_RT", rack::bench::cpu_model().c_str(),
                o.priority, o.cpu, o.rounds, static_cast<long long>(o.gap_us));

    const uint64_t per_block = (o.iterations + static_cast<uint64_t>(o.rounds) - 1) / static_cast<uint64_t>(o.rounds);
    std::vector<int64_t> fill_latency, fill_stats, rpc_latency, rpc_stats;
    for (auto* v : {&fill_latency, &fill_stats, &rpc_latency, &rpc_stats})
      v->reserve(per_block * static_cast<uint64_t>(o.rounds));
    uint64_t failures = 0;
    rt::Thread client;
    client.start(
        rt::ThreadConfig{"bench-lat-cli", o.priority, o.cpu, 256 * 1024},
        [&] {
          wire::LatencyHistogram h;
          wire::StatsReply s;
          alignas(8) static std::byte buf[4096];
          const tims::Address dest = gen->address();
          for (int round = 0; round < o.rounds; ++round) {
            for (uint64_t i = 0; i < per_block; ++i) {
              if (o.gap_us > 0) rt::sleep_for(o.gap_us * rt::kNsPerUs);
              int64_t t0 = rt::monotonic_ns();
              gen->fill_latency(h);
              int64_t t1 = rt::monotonic_ns();
              fill_latency.push_back(t1 - t0);
              t0 = rt::monotonic_ns();
              gen->fill_stats(s);
              t1 = rt::monotonic_ns();
              fill_stats.push_back(t1 - t0);
            }
            // RPCs: one side's block, then the other's (the order swaps every round).
            for (int side = 0; side < 2; ++side) {
              const bool hist = (side + round) % 2 == 0;
              auto& out = hist ? rpc_latency : rpc_stats;
              for (uint64_t i = 0; i < per_block; ++i) {
                if (o.gap_us > 0) rt::sleep_for(o.gap_us * rt::kNsPerUs);
                const int64_t t0 = rt::monotonic_ns();
                const auto r = endpoint.call(dest, hist ? tims::msg::kGetLatency : tims::msg::kGetStats,
                                             std::span<std::byte>(buf), rt::kNsPerSec);
                const int64_t t1 = rt::monotonic_ns();
                if (r.status != tims::CallStatus::kOk ||
                    r.reply.type != (hist ? tims::msg::kLatency : tims::msg::kStats)) {
                  ++failures;
                }
                out.push_back(t1 - t0);
              }
            }
          }
        },
        o.priority == 0);
    client.join();
    const wire::StatsReply final_stats = [&] {
      wire::StatsReply s;
      gen->fill_stats(s);
      return s;
    }();
    print_part("fill: the command task's work per request", fill_latency, fill_stats, 0);
    print_part("rpc: round trip to the command task", rpc_latency, rpc_stats, failures);
    std::printf("the generator's data task meanwhile: %llu samples, %llu overruns, wake-up p99 %.1f us\n",
                static_cast<unsigned long long>(final_stats.data.samples),
                static_cast<unsigned long long>(final_stats.data.overruns),
                static_cast<double>(final_stats.data.latency_p99_ns) / 1e3);
    if (!o.json.empty()) {
      using rack::bench::json_escape;
      using rack::bench::json_percentiles;
      const auto comparison = [](const char* name, std::vector<int64_t>& a, std::vector<int64_t>& b) {
        return std::string("{\"name\": \"") + name +
               "\", \"rack_label\": \"GET_LATENCY\", \"reference_label\": \"GET_STATS\", \"rack\": " +
               json_percentiles(percentiles_of(a)) + ", \"reference\": " + json_percentiles(percentiles_of(b)) +
               ", \"metric\": \"p50_ns\"}";
      };
      std::ofstream f(o.json);
      f << "{\"benchmark\": \"latency_reply\", \"machine\": " << rack::bench::json_machine()
        << ", \"title\": \"bench_latency_reply: GET_LATENCY (the wake-up histogram, 40 buckets) vs GET_STATS\""
        << ", \"about\": \""
        << json_escape(
               "What asking a running component for its data task's wake-up latency histogram costs, beside "
               "GET_STATS in the same run: the command task's work per request (fill), and the round trip from a "
               "SCHED_FIFO client (rpc), in alternating blocks. A Generator's data task runs at 1 kHz meanwhile.")
        << "\", \"comparisons\": [" << comparison("fill: the command task's work per request", fill_latency, fill_stats)
        << ", " << comparison("rpc: round trip to the command task", rpc_latency, rpc_stats) << "], \"notes\": [\""
        << json_escape("The generator's data task meanwhile: " + std::to_string(final_stats.data.samples) +
                       " samples, " + std::to_string(final_stats.data.overruns) + " overruns; " +
                       std::to_string(failures) + " failed calls.")
        << "\"]}\n";
      if (!f) throw std::runtime_error("cannot write " + o.json);
    }
    executor.router().remove(mailbox.address());
    executor.stop();
    return failures == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_latency_reply: %s\n", e.what());
    return 1;
  }
}
