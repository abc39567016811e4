// bench_gdos: what a GDOS log call costs an RT task, beside snprintf of the same
// message into a stack buffer (the reference), and how many records per second one
// host publishes on LCM, beside formatting and publishing the same records directly
// (no rings, no GDOS thread: the reference for throughput).
//
// Part 1 (call cost): one SCHED_FIFO thread pinned to a CPU alternates blocks of
// gdos::log() into its bound ring and blocks of snprintf() of the same format and
// arguments into a 256-byte stack buffer. Each sample is the time of 8 calls
// (clock_gettime around them) divided by 8, the same for both sides; the ring is
// emptied between blocks without formatting (untimed), so every timed log call takes
// the full encode path, never the (cheaper) drop path. Several messages: integers
// only, with doubles, with strings and a TiMS address.
//
// Part 2 (throughput): an Executor with one periodic (1 ms) component that logs
// `rate/1000` records per cycle, GDOS published on a private LCM port, and a
// GdosSubscriber in the same process counting what arrives. Rates ramp up; per rate:
// offered, drained, dropped in the ring, published, received, lost. Reference: one
// thread formats the same record with snprintf and publishes through GdosPublisher
// as fast as it can, the subscriber counting.
//
// Prints a Markdown section (bench/RESULTS.md) and optionally JSON.
#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "rack/components/builtin.h"
#include "rack/components/class_ids.h"
#include "rack/core/data_component.h"
#include "rack/core/executor.h"
#include "rack/core/gdos.h"
#include "rack/core/host_config.h"
#include "rack/interfaces/demo.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/thread.h"
#include "rack/tims/gdos_lcm.h"

namespace rack::bench {
namespace {

struct Options {
  int cpu = 1;
  int priority = 80;
  int samples = 20000;  // per message and side (each sample = 8 calls)
  int rate_seconds = 1;
  int port = 7891;
  std::vector<int> rates{10000, 50000, 100000, 200000, 400000, 800000, 1600000};
  std::string json;
};

constexpr int kBatch = 8;
constexpr int kBlock = 256;  // samples per block before switching sides

// ---- part 1 ------------------------------------------------------------------

struct CostResult {
  std::string label;
  std::string format;
  Percentiles gdos, ref;
};

template <class LogFn, class RefFn>
CostResult measure_cost(const Options& o, const std::string& label, const std::string& format, LogFn log_fn,
                        RefFn ref_fn) {
  CostResult res;
  res.label = label;
  res.format = format;
  std::vector<int64_t> g, r;
  g.reserve(static_cast<std::size_t>(o.samples));
  r.reserve(static_cast<std::size_t>(o.samples));
  gdos::LogRing ring(kBlock * kBatch * 2, "bench");
  rt::Thread t;
  t.start(
      {"bench-gdos", o.priority, o.cpu, 256 * 1024},
      [&] {
        gdos::bind_thread_ring(&ring);
        auto empty = [&] {
          while (ring.peek() != nullptr) ring.pop();
        };
        for (int warm = 0; warm < 2000; ++warm) {
          log_fn(warm);
          ref_fn(warm);
          empty();
        }
        int i = 0;
        while (static_cast<int>(g.size()) < o.samples) {
          for (int k = 0; k < kBlock; ++k, ++i) {
            const int64_t t0 = rt::monotonic_ns();
            for (int b = 0; b < kBatch; ++b) log_fn(i + b);
            const int64_t t1 = rt::monotonic_ns();
            g.push_back((t1 - t0) / kBatch);
          }
          empty();
          for (int k = 0; k < kBlock; ++k, ++i) {
            const int64_t t0 = rt::monotonic_ns();
            for (int b = 0; b < kBatch; ++b) ref_fn(i + b);
            const int64_t t1 = rt::monotonic_ns();
            r.push_back((t1 - t0) / kBatch);
          }
        }
        gdos::bind_thread_ring(nullptr);
      },
      true);
  t.join();
  if (ring.dropped() != 0)
    std::fprintf(stderr, "bench_gdos: unexpected drops in part 1: %llu\n",
                 static_cast<unsigned long long>(ring.dropped()));
  res.gdos = percentiles_of(g);
  res.ref = percentiles_of(r);
  return res;
}

volatile int g_sink = 0;  // keeps snprintf's result alive

// ---- part 2 ------------------------------------------------------------------

class FloodLogger final : public DataComponent<interfaces::GeneratorData> {
 public:
  FloodLogger()
      : DataComponent(DataTaskMode::kPeriodic),
        per_cycle_(declare_int("per_cycle", 0, {.doc = "records per cycle", .min = 0, .max = 1000000})) {}
  std::atomic<uint64_t> offered{0};

 protected:
  HookResult loop() override {
    const int64_t n = per_cycle_.get_int();
    for (int64_t i = 0; i < n; ++i) {
      log_info("scan %lld: %d points, nearest %.3f m at %s", static_cast<long long>(i), 541,
               0.25 * static_cast<double>(i), "front");
    }
    offered.fetch_add(static_cast<uint64_t>(n), std::memory_order_relaxed);
    return HookResult::kOk;
  }

 private:
  Parameter& per_cycle_;
};

struct RateResult {
  int rate = 0;
  double seconds = 0;
  uint64_t offered = 0, drained = 0, dropped = 0, published = 0, received = 0, lost = 0;
};

struct Receiver {
  // A 4 MiB socket buffer (DESIGN.md: without it LCM loses bursts in the kernel).
  explicit Receiver(const std::string& url) : sub(url + "&recv_buf_size=4194304", tims::kGdosChannel, false, "bench") {
    thread = std::thread([this] {
      while (!stop.load()) sub.poll(50, [this](const tims::GdosRecord&) { received.fetch_add(1); });
    });
  }
  ~Receiver() {
    stop.store(true);
    thread.join();
  }
  tims::GdosSubscriber sub;
  std::atomic<uint64_t> received{0};
  std::atomic<bool> stop{false};
  std::thread thread;
};

std::vector<RateResult> measure_rates(const Options& o, const std::string& url) {
  ComponentRegistry registry;
  ComponentClass cls;
  cls.impl = "FloodLogger";
  cls.class_id = class_ids::kGenerator;
  cls.description = "bench";
  cls.make = [] { return std::unique_ptr<Component>(new FloodLogger()); };
  registry.add(std::move(cls));
  const std::string yaml = "host: bench\nsystem: 0\nlcm_url: \"" + url +
                           "\"\nheap_prefault_mib: 16\n"
                           "gdos: {level: info, stderr: never, ring: 8192, drain_ms: 10}\n"
                           "components:\n"
                           "  - name: flood\n    class: FloodLogger\n    instance: 1\n"
                           "    data_task: {priority: " +
                           std::to_string(o.priority) + ", cpu: " + std::to_string(o.cpu) + ", period_ms: 1}\n";
  auto loaded = load_host_text(yaml, "bench.yaml", registry, rt::probe_capabilities());
  if (!loaded.errors.empty()) {
    std::fprintf(stderr, "bench_gdos: %s\n", loaded.errors.front().str().c_str());
    std::exit(1);
  }
  ExecutorOptions eo;
  eo.log = [](const std::string&) {};
  Executor ex(std::move(loaded.host), eo);
  ex.start();
  Receiver rx(url);
  auto* flood = dynamic_cast<FloodLogger*>(ex.find("flood"));
  // ON through the executor's endpoint.
  alignas(8) std::byte buf[512];
  (void)ex.endpoint().call(flood->address(), tims::msg::kOn, std::span<std::byte>(buf), rt::kNsPerSec);
  std::vector<RateResult> out;
  for (int rate : o.rates) {
    (void)flood->parameters().find("per_cycle")->set_from_text("0");
    rt::sleep_for(200 * rt::kNsPerMs);
    ex.flush_log();
    rt::sleep_for(100 * rt::kNsPerMs);
    const uint64_t off0 = flood->offered.load();
    const auto h0 = ex.gdos_hub().counters();
    const uint64_t rx0 = rx.received.load();
    const uint64_t lost0 = rx.sub.counters().lost;
    const int64_t t0 = rt::monotonic_ns();
    (void)flood->parameters().find("per_cycle")->set_from_text(std::to_string(rate / 1000));
    rt::sleep_for(o.rate_seconds * rt::kNsPerSec);
    (void)flood->parameters().find("per_cycle")->set_from_text("0");
    const int64_t t1 = rt::monotonic_ns();
    rt::sleep_for(300 * rt::kNsPerMs);  // the GDOS thread and the receiver catch up
    ex.flush_log();
    rt::sleep_for(200 * rt::kNsPerMs);
    const auto h1 = ex.gdos_hub().counters();
    RateResult r;
    r.rate = rate;
    r.seconds = static_cast<double>(t1 - t0) * 1e-9;
    r.offered = flood->offered.load() - off0;
    r.drained = h1.records - h0.records;
    r.dropped = h1.dropped - h0.dropped;
    r.received = rx.received.load() - rx0;
    r.lost = rx.sub.counters().lost - lost0;
    r.published = r.drained;  // every drained record is handed to the publisher
    out.push_back(r);
    std::fprintf(stderr, "bench_gdos: rate %d/s: offered %llu drained %llu dropped %llu received %llu lost %llu\n",
                 rate, static_cast<unsigned long long>(r.offered), static_cast<unsigned long long>(r.drained),
                 static_cast<unsigned long long>(r.dropped), static_cast<unsigned long long>(r.received),
                 static_cast<unsigned long long>(r.lost));
  }
  ex.stop();
  return out;
}

struct DirectResult {
  double seconds = 0;
  uint64_t published = 0, received = 0, lost = 0;
};

DirectResult measure_direct(const Options& o, const std::string& url) {
  Receiver rx(url);
  tims::GdosPublisherConfig pc;
  pc.url = url;
  pc.host = "bench-direct";
  pc.pid = static_cast<int32_t>(getpid());
  tims::GdosPublisher pub(pc);
  DirectResult d;
  const int64_t t0 = rt::monotonic_ns();
  const int64_t end = t0 + o.rate_seconds * rt::kNsPerSec;
  uint64_t seq = 0;
  char text[256];
  while (rt::monotonic_ns() < end) {
    // The same batching as the GDOS thread (one pass = up to a batch), without rings.
    for (int i = 0; i < 100; ++i) {
      const int n = std::snprintf(text, sizeof text, "scan %lld: %d points, nearest %.3f m at %s",
                                  static_cast<long long>(i), 541, 0.25 * i, "front");
      pub.add(0x400100u, "flood", 3, rt::host_time_ns(), ++seq, 0, std::string_view(text, static_cast<std::size_t>(n)));
    }
    pub.flush();
  }
  d.seconds = static_cast<double>(rt::monotonic_ns() - t0) * 1e-9;
  d.published = seq;
  rt::sleep_for(500 * rt::kNsPerMs);
  d.received = rx.received.load();
  d.lost = rx.sub.counters().lost;
  return d;
}

std::string row(const char* label, const Percentiles& p) {
  char b[256];
  std::snprintf(b, sizeof b, "| %s | %.0f | %.0f | %.0f | %.0f | %.0f | %.0f |", label, p.min_ns, p.p50_ns, p.p90_ns,
                p.p99_ns, p.p999_ns, p.max_ns);
  return b;
}

}  // namespace
}  // namespace rack::bench

int main(int argc, char** argv) {
  using namespace rack;
  using namespace rack::bench;
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_gdos: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--cpu") o.cpu = std::stoi(next());
    else if (a == "--priority") o.priority = std::stoi(next());
    else if (a == "--samples") o.samples = std::stoi(next());
    else if (a == "--rate-seconds") o.rate_seconds = std::stoi(next());
    else if (a == "--port") o.port = std::stoi(next());
    else if (a == "--json") o.json = next();
    else if (a == "--quick") {
      o.samples = 5000;
      o.rates = {10000, 100000, 400000, 800000};
    } else if (a == "-h" || a == "--help") {
      std::puts(
          "usage: bench_gdos [--quick] [--cpu C] [--priority P] [--samples N] [--rate-seconds S]\n"
          "                  [--port PORT] [--json FILE]\n"
          "Part 1: cost of a GDOS log call in an RT task vs snprintf of the same message (same\n"
          "thread, same run, alternating blocks). Part 2: records per second one host publishes\n"
          "on LCM (udpm on 239.255.76.67:PORT, ttl=0) vs formatting and publishing directly.\n"
          "Prints a Markdown section for bench/RESULTS.md.");
      return 0;
    } else {
      std::fprintf(stderr, "bench_gdos: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  const auto caps = rt::probe_capabilities();
  (void)rt::apply_memory_policy(32u << 20);
  const std::string url = "udpm://239.255.76.67:" + std::to_string(o.port) + "?ttl=0";

  // Part 1.
  const tims::Address dest = tims::Address::make(0, class_ids::kPosition, 2);
  gdos::LogSource src(tims::Address::make(0, class_ids::kLadar, 1), "ladar", gdos::Level::kInfo);
  std::vector<CostResult> costs;
  char buf[256];
  costs.push_back(measure_cost(
      o, "integers", "cycle %d: %u points, %ld us late, flags %#x",
      [&](int i) {
        gdos::log(src, gdos::Level::kInfo, "cycle %d: %u points, %ld us late, flags %#x", i, 541u, 17L * i, 0x2au);
      },
      [&](int i) {
        g_sink = std::snprintf(buf, sizeof buf, "cycle %d: %u points, %ld us late, flags %#x", i, 541u, 17L * i, 0x2au);
      }));
  costs.push_back(measure_cost(
      o, "doubles", "pose x %.3f y %.3f phi %.4f v %g",
      [&](int i) {
        gdos::log(src, gdos::Level::kInfo, "pose x %.3f y %.3f phi %.4f v %g", 1.5 * i, -0.25 * i, 0.001 * i, 0.7);
      },
      [&](int i) {
        g_sink = std::snprintf(buf, sizeof buf, "pose x %.3f y %.3f phi %.4f v %g", 1.5 * i, -0.25 * i, 0.001 * i, 0.7);
      }));
  costs.push_back(measure_cost(
      o, "mixed + strings", "scan %d to %s (%s): nearest %.3f m, %zu points",
      [&](int i) {
        gdos::log(src, gdos::Level::kInfo, "scan %d to %s (%s): nearest %.3f m, %zu points", i, dest, "front ladar",
                  0.25 * i, static_cast<std::size_t>(541));
      },
      [&](int i) {
        g_sink = std::snprintf(buf, sizeof buf, "scan %d to %s (%s): nearest %.3f m, %zu points", i, "Position(0/2)",
                               "front ladar", 0.25 * i, static_cast<std::size_t>(541));
      }));

  // Part 2.
  const auto rates = measure_rates(o, url);
  const auto direct = measure_direct(o, url);

  // Report.
  std::string md;
  char line[512];
  md += "## GDOS: log call cost and records per second (bench_gdos)\n\n";
  std::snprintf(line, sizeof line,
                "Command: `%s%s`. Kernel `%s` (PREEMPT_RT: %s), %s; the log thread SCHED_FIFO %d on CPU %d (%s). "
                "Other helpers were building and testing on this 2-CPU VM at the same time; ratios are from the same "
                "run, same thread, alternating blocks of %d samples.\n\n",
                argv[0], argc > 1 ? " ..." : "", kernel_string().c_str(), kernel_is_preempt_rt() ? "yes" : "no",
                cpu_model().c_str(), o.priority, o.cpu, caps.sched_fifo ? "granted" : "refused: SCHED_OTHER", kBlock);
  md += line;
  md += "### Cost of one call in an RT task (ns per call; each sample is 8 calls / 8)\n\n";
  for (const auto& c : costs) {
    std::snprintf(line, sizeof line, "**%s**: `\"%s\"`\n\n", c.label.c_str(), c.format.c_str());
    md += line;
    md += "| side | min | p50 | p90 | p99 | p99.9 | max |\n|---|---|---|---|---|---|---|\n";
    md += row("GDOS log call (encode into the task's ring)", c.gdos) + "\n";
    md += row("snprintf into a stack buffer (reference)", c.ref) + "\n";
    std::snprintf(line, sizeof line, "\nRatio GDOS / snprintf: **p50 %.2fx** (target < 0.5x: **%s**), p99 %.2fx.\n\n",
                  c.gdos.p50_ns / c.ref.p50_ns, c.gdos.p50_ns < 0.5 * c.ref.p50_ns ? "met" : "not met",
                  c.gdos.p99_ns / c.ref.p99_ns);
    md += line;
  }
  md += "### Records per second one host publishes\n\n";
  md +=
      "One periodic (1 ms) component logs rate/1000 records per cycle (`\"scan %lld: %d points, nearest %.3f m at "
      "%s\"`); ring 8192 records, GDOS thread every 10 ms, published on LCM udpm (loopback, ttl=0), a subscriber in "
      "the same process (recv_buf_size=4194304) counts arrivals.\n\n";
  md +=
      "| offered rate | offered | drained + published (all records of the host) | dropped (ring full) | received | lost on LCM | delivered/s |\n"
      "|---|---|---|---|---|---|---|\n";
  double sustained = 0;
  for (const auto& r : rates) {
    const double per_s = static_cast<double>(r.received) / r.seconds;
    std::snprintf(line, sizeof line, "| %d/s | %llu | %llu | %llu | %llu | %llu | %.0f |\n", r.rate,
                  static_cast<unsigned long long>(r.offered), static_cast<unsigned long long>(r.drained),
                  static_cast<unsigned long long>(r.dropped), static_cast<unsigned long long>(r.received),
                  static_cast<unsigned long long>(r.lost), per_s);
    md += line;
    // (received may exceed offered by the executor's own records, e.g. an overrun report)
    if (r.dropped == 0 && r.lost == 0 && r.received >= r.offered) sustained = std::max(sustained, per_s);
  }
  const double direct_rate = static_cast<double>(direct.received) / direct.seconds;
  std::snprintf(
      line, sizeof line,
      "\nSustained without any loss: **%.0f records/s** (delivered at the highest offered rate with "
      "nothing dropped or lost; the limit lies between it and the next rate). Reference in the same run: one thread formatting with snprintf and publishing the same records "
      "in the same batches directly (no rings, no GDOS thread): %llu published in %.1f s, %llu received, "
      "%llu lost: **%.0f records/s**.\n\n",
      sustained, static_cast<unsigned long long>(direct.published), direct.seconds,
      static_cast<unsigned long long>(direct.received), static_cast<unsigned long long>(direct.lost), direct_rate);
  md += line;
  std::fputs(md.c_str(), stdout);
  if (!o.json.empty()) {
    std::string j = "{\"machine\":" + json_machine() + ",\"cost\":[";
    for (std::size_t i = 0; i < costs.size(); ++i) {
      j += (i ? "," : "") + std::string("{\"label\":\"") + json_escape(costs[i].label) + "\",\"format\":\"" +
           json_escape(costs[i].format) + "\",\"gdos\":" + json_percentiles(costs[i].gdos) +
           ",\"snprintf\":" + json_percentiles(costs[i].ref) + "}";
    }
    j += "],\"rates\":[";
    for (std::size_t i = 0; i < rates.size(); ++i) {
      const auto& r = rates[i];
      j += (i ? "," : "") + std::string("{\"rate\":") + std::to_string(r.rate) +
           ",\"offered\":" + std::to_string(r.offered) + ",\"drained\":" + std::to_string(r.drained) +
           ",\"dropped\":" + std::to_string(r.dropped) + ",\"received\":" + std::to_string(r.received) +
           ",\"lost\":" + std::to_string(r.lost) + ",\"seconds\":" + json_number(r.seconds) + "}";
    }
    j += "],\"priority\":" + std::to_string(o.priority) + ",\"cpu\":" + std::to_string(o.cpu) +
         ",\"sustained_records_per_s\":" + json_number(sustained) +
         ",\"direct_records_per_s\":" + json_number(direct_rate) + "}";
    write_file(o.json, j);
  }
  return 0;
}
