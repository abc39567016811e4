// bench_rpc: round trip of a TiMS RPC (GET_STATUS) between a client task and a
// component's command task inside one executor, beside raw ping-pongs of two
// SCHED_FIFO threads in the same binary, with the same placement and priority.
//
//   reference "futex":      two threads hand a ball back and forth through one futex
//                           word (FUTEX_WAIT/FUTEX_WAKE_PRIVATE, no spinning): the
//                           cheapest blocking hand-off Linux offers. The ratio target
//                           is against this one.
//   diagnostic "pi-condvar": the same ping-pong through two channels of
//                           {PI mutex, condvar on CLOCK_MONOTONIC, flag}, i.e. the
//                           primitives a TiMS mailbox is built from, without TiMS.
//   diagnostic "pi-condvar-timed": the same with the reader's wait bounded by a
//                           deadline 1 s ahead, as Endpoint::call() waits.
//   diagnostic "pi-futex":  the same channels, but the reader sleeps on a bare futex
//                           word (rt::PiCondVar is such a word since it replaced
//                           glibc's condvar, whose PI re-lock made every next unlock a
//                           FUTEX_UNLOCK_PI system call): the two should now match.
//   "rack-rpc":             tims::Endpoint::call(GET_STATUS) from a client thread to a
//                           Generator's command task in a rack::Executor (lcm: false),
//                           reply back into the client's own Mailbox.
//
// Each round trip is timed by the client with CLOCK_MONOTONIC (clock_gettime, vDSO).
// Mechanisms are run in alternating blocks (rounds) so slow drifts of a shared VM hit
// all of them alike. Between round trips the client sleeps --gap-us so the measured
// CPU is not 100% busy with RT threads (the kernel's RT throttling / fair server would
// otherwise steal 50 ms per second and show up as max latency).
//
// Needs root (SCHED_FIFO, mlockall). See bench/run and bench/RESULTS.md.
#include <linux/futex.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_common.h"
#include "rack/components/builtin.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/pi_mutex.h"
#include "rack/rt/thread.h"
#include "rack/tims/endpoint.h"

namespace {

using rack::bench::Percentiles;
namespace rt = rack::rt;
namespace tims = rack::tims;

constexpr const char* kUsage =
    "usage: bench_rpc [--iterations N] [--cpu-mode same|cross|both] [--json FILE]\n"
    "                 [--priority P] [--server-cpu C] [--cross-cpu C] [--rounds R]\n"
    "                 [--gap-us G] [--warmup W] [--pm-qos] [--no-diagnostics] [--only M] [--verbose]\n"
    "  --iterations N   timed round trips per mechanism and placement (default 20000)\n"
    "  --cpu-mode M     same: client and server pinned to one CPU; cross: on two CPUs;\n"
    "                   both (default)\n"
    "  --json FILE      write machine-readable results\n"
    "  --priority P     SCHED_FIFO priority of every measured thread (default 80)\n"
    "  --server-cpu C   CPU of the server side (command task / reference server), default 0\n"
    "  --cross-cpu C    CPU of the client in cross mode (default: another online CPU)\n"
    "  --rounds R       alternate the mechanisms in R blocks (default 4)\n"
    "  --gap-us G       client sleeps G us between round trips (default 100)\n"
    "  --warmup W       untimed round trips at the start of every block (default 200)\n"
    "  --pm-qos         hold /dev/cpu_dma_latency at 0 during the run (default: leave it)\n"
    "  --no-diagnostics skip the diagnostic references (pi_condvar, pi_condvar_timed, pi_futex)\n"
    "  --only M         run one mechanism only: futex, rack, pi_condvar, pi_condvar_timed or\n"
    "                   pi_futex\n"
    "                   (for strace/perf)\n";

struct Options {
  uint64_t iterations = 20000;
  std::string cpu_mode = "both";
  std::string json;
  int priority = 80;
  int server_cpu = 0;
  int cross_cpu = -1;
  int rounds = 4;
  int64_t gap_us = 100;
  uint64_t warmup = 200;
  bool pm_qos = false;
  bool diagnostics = true;
  std::string only;  // "" or one mechanism key ("rack" for rack_rpc)
  bool verbose = false;
};

struct Placement {
  std::string mode;
  int server_cpu = 0;
  int client_cpu = 0;
};

// ---- raw futex ping-pong ----------------------------------------------------

long futex(std::atomic<uint32_t>* word, int op, uint32_t val) noexcept {
  return syscall(SYS_futex, reinterpret_cast<uint32_t*>(word), op, val, nullptr, nullptr, 0);
}
void futex_wait(std::atomic<uint32_t>* word, uint32_t expected) noexcept {
  (void)futex(word, FUTEX_WAIT_PRIVATE, expected);
}
void futex_wake(std::atomic<uint32_t>* word) noexcept { (void)futex(word, FUTEX_WAKE_PRIVATE, 1); }

struct BlockResult {
  uint64_t voluntary_switches = 0;  // client thread, over the timed iterations
  uint64_t involuntary_switches = 0;
  uint64_t failures = 0;
};

// The client-side loop shared by every mechanism: warm-up, gap, timing, rusage.
template <typename RoundTrip>
BlockResult client_loop(const Options& o, uint64_t count, std::vector<int64_t>& out, RoundTrip&& round_trip) {
  BlockResult br;
  const int64_t gap_ns = o.gap_us * rt::kNsPerUs;
  rusage before{};
  for (uint64_t i = 0; i < o.warmup + count; ++i) {
    if (i == o.warmup) getrusage(RUSAGE_THREAD, &before);
    if (gap_ns > 0) rt::sleep_for(gap_ns);
    const int64_t t0 = rt::monotonic_ns();
    const bool ok = round_trip();
    const int64_t t1 = rt::monotonic_ns();
    if (!ok) ++br.failures;
    if (i >= o.warmup) out.push_back(t1 - t0);  // capacity reserved by the caller
  }
  rusage after{};
  getrusage(RUSAGE_THREAD, &after);
  br.voluntary_switches = static_cast<uint64_t>(after.ru_nvcsw - before.ru_nvcsw);
  br.involuntary_switches = static_cast<uint64_t>(after.ru_nivcsw - before.ru_nivcsw);
  return br;
}

rt::ThreadConfig thread_config(const char* name, int priority, int cpu) {
  return rt::ThreadConfig{name, priority, cpu, 256 * 1024};
}

BlockResult run_futex_block(const Options& o, const Placement& pl, uint64_t count, std::vector<int64_t>& out) {
  // 0: the ball is with the client; 1: with the server; 2: stop.
  alignas(64) std::atomic<uint32_t> word{0};
  BlockResult result;
  rt::Thread server;
  rt::Thread client;
  server.start(
      thread_config("ref-futex-srv", o.priority, pl.server_cpu),
      [&word] {
        for (;;) {
          uint32_t w;
          while ((w = word.load(std::memory_order_acquire)) == 0) futex_wait(&word, 0);
          if (w == 2) return;
          word.store(0, std::memory_order_release);  // release: the client sees what we did
          futex_wake(&word);
        }
      },
      false);
  client.start(
      thread_config("ref-futex-cli", o.priority, pl.client_cpu),
      [&] {
        result = client_loop(o, count, out, [&word] {
          word.store(1, std::memory_order_release);
          futex_wake(&word);
          while (word.load(std::memory_order_acquire) == 1) futex_wait(&word, 1);
          return true;
        });
        word.store(2, std::memory_order_release);
        futex_wake(&word);
      },
      false);
  client.join();
  server.join();
  return result;
}

// ---- PI mutex + condvar ping-pong (the mailbox's primitives, no TiMS) ---------

// Timed: the reader waits with a deadline 1 s ahead, as tims::Endpoint::call does
// (pthread_cond_timedwait: the kernel arms and cancels an hrtimer on every wait).
template <bool Timed>
struct CondvarChannel {
  rt::PiMutex mutex;
  rt::PiCondVar cv;
  bool full = false;  // guarded by mutex
  bool stop = false;  // guarded by mutex
  void send() noexcept {
    {
      rt::PiLock lock(mutex);
      full = true;
    }
    cv.notify_one();
  }
  bool receive() noexcept {
    const int64_t deadline = Timed ? rt::monotonic_ns() + rt::kNsPerSec : -1;
    rt::PiLock lock(mutex);
    while (!full && !stop) cv.wait_until(mutex, deadline);
    if (!full) return false;
    full = false;
    return true;
  }
  void close() noexcept {
    {
      rt::PiLock lock(mutex);
      stop = true;
    }
    cv.notify_all();
  }
};

// The same channel with the wait on a futex word: the reader samples `seq` under the
// mutex, unlocks, and sleeps only while `seq` is unchanged; a sender bumps `seq` after
// its critical section and wakes. The PI mutex is then only ever taken uncontended
// (user-space CAS, no system call) in this ping-pong.
struct FutexChannel {
  rt::PiMutex mutex;
  alignas(64) std::atomic<uint32_t> seq{0};  // release/acquire: pairs the bump with the re-check
  bool full = false;                         // guarded by mutex
  bool stop = false;                         // guarded by mutex
  void bump_and_wake() noexcept {
    seq.fetch_add(1, std::memory_order_release);
    futex_wake(&seq);
  }
  void send() noexcept {
    {
      rt::PiLock lock(mutex);
      full = true;
    }
    bump_and_wake();
  }
  bool receive() noexcept {
    mutex.lock();
    while (!full && !stop) {
      const uint32_t s = seq.load(std::memory_order_acquire);
      mutex.unlock();
      futex_wait(&seq, s);
      mutex.lock();
    }
    const bool got = full;
    full = false;
    mutex.unlock();
    return got;
  }
  void close() noexcept {
    {
      rt::PiLock lock(mutex);
      stop = true;
    }
    bump_and_wake();
  }
};

template <typename Channel>
BlockResult run_channel_block(const Options& o, const Placement& pl, uint64_t count, std::vector<int64_t>& out) {
  Channel request;
  Channel reply;
  BlockResult result;
  rt::Thread server;
  rt::Thread client;
  server.start(
      thread_config("ref-ch-srv", o.priority, pl.server_cpu),
      [&] {
        while (request.receive()) reply.send();
      },
      false);
  client.start(
      thread_config("ref-ch-cli", o.priority, pl.client_cpu),
      [&] {
        result = client_loop(o, count, out, [&] {
          request.send();
          return reply.receive();
        });
        request.close();
      },
      false);
  client.join();
  server.join();
  return result;
}

// ---- RACK-RT RPC ----------------------------------------------------------------

struct RackSide {
  std::unique_ptr<rack::Executor> executor;
  std::unique_ptr<tims::Mailbox> mailbox;  // the client's reply mailbox
  std::unique_ptr<tims::Endpoint> endpoint;
  tims::Address server;
};

std::string host_text(const Options& o) {
  std::ostringstream y;
  y << "host: bench-rpc\n"
       "system: 0\n"
       "host_id: 0\n"
       "lcm: false\n"
       "heap_prefault_mib: 16\n"
       "components:\n"
       "  - name: gen\n"
       "    class: Generator\n"
       "    instance: 0\n"
       "    autostart: false\n"
       "    command_task: {priority: "
    << o.priority << ", cpu: " << o.server_cpu
    << "}\n"
       // The data task must exist for a Generator; once a second, below the command task.
       "    data_task: {priority: "
    << (o.priority > 1 ? o.priority - 1 : 1) << ", cpu: " << o.server_cpu << ", period_ms: 1000}\n";
  return y.str();
}

RackSide start_rack(const Options& o, const rt::RtCapabilities& caps) {
  rack::ComponentRegistry registry;
  rack::components::register_builtin(registry);
  auto loaded = rack::load_host_text(host_text(o), "bench_rpc.yaml", registry, caps);
  if (!loaded.errors.empty()) {
    std::string all;
    for (const auto& e : loaded.errors) all += e.str() + "\n";
    throw std::runtime_error("host text rejected:\n" + all);
  }
  RackSide side;
  rack::ExecutorOptions eo;
  eo.allow_rt_fallback = false;
  const bool verbose = o.verbose;
  eo.log = [verbose](const std::string& line) {
    if (verbose) std::fprintf(stderr, "rackd: %s\n", line.c_str());
  };
  side.executor = std::make_unique<rack::Executor>(std::move(loaded.host), eo);
  side.executor->start();
  rack::Component* gen = side.executor->find("gen");
  if (gen == nullptr) throw std::runtime_error("component 'gen' not found");
  side.server = gen->address();
  side.mailbox = std::make_unique<tims::Mailbox>(tims::Address::make(0, tims::classes::kTool, 1, 0), 8, 256);
  side.executor->router().add(*side.mailbox);
  side.endpoint = std::make_unique<tims::Endpoint>(side.executor->router(), *side.mailbox,
                                                   static_cast<uint8_t>(o.priority));
  return side;
}

BlockResult run_rack_block(const Options& o, const Placement& pl, RackSide& side, uint64_t count,
                           std::vector<int64_t>& out) {
  BlockResult result;
  rt::Thread client;
  client.start(
      thread_config("rack-rpc-cli", o.priority, pl.client_cpu),
      [&] {
        alignas(8) std::byte buf[256];
        tims::Endpoint& ep = *side.endpoint;
        const tims::Address dest = side.server;
        result = client_loop(o, count, out, [&] {
          const tims::CallResult r = ep.call(dest, tims::msg::kGetStatus, std::span<std::byte>(buf), rt::kNsPerSec);
          return r.status == tims::CallStatus::kOk &&
                 (r.reply.type == tims::msg::kDisabled || r.reply.type == tims::msg::kEnabled);
        });
      },
      false);
  client.join();
  return result;
}

// ---- driver ----------------------------------------------------------------------

struct Mechanism {
  std::string key;    // json key
  std::string label;  // table label
  std::vector<int64_t> samples;
  uint64_t voluntary = 0, involuntary = 0, failures = 0;
  Percentiles p;
  void add(const BlockResult& b) {
    voluntary += b.voluntary_switches;
    involuntary += b.involuntary_switches;
    failures += b.failures;
  }
};

struct ModeResult {
  Placement placement;
  std::vector<Mechanism> mechanisms;  // [0] futex, [1] rack, [2] pi-condvar (optional)
  double ratio_p50 = 0, ratio_p99 = 0;
};

void print_mode(const ModeResult& m, const Options& o) {
  std::printf(
      "\n== placement '%s': client CPU %d, server CPU %d, SCHED_FIFO %d, %llu round trips each, "
      "gap %lld us ==\n",
      m.placement.mode.c_str(), m.placement.client_cpu, m.placement.server_cpu, o.priority,
      static_cast<unsigned long long>(o.iterations), static_cast<long long>(o.gap_us));
  std::printf("%-22s %9s %9s %9s %9s %9s %9s   %s\n", "mechanism (us)", "min", "p50", "p90", "p99", "p99.9", "max",
              "client ctx sw/rt (vol/invol)");
  for (const auto& mech : m.mechanisms) {
    if (mech.p.samples == 0) continue;
    const Percentiles& p = mech.p;
    const double n = p.samples > 0 ? static_cast<double>(p.samples) : 1.0;
    std::printf("%-22s %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f   %.2f / %.3f%s\n", mech.label.c_str(),
                rack::bench::us(p.min_ns), rack::bench::us(p.p50_ns), rack::bench::us(p.p90_ns),
                rack::bench::us(p.p99_ns), rack::bench::us(p.p999_ns), rack::bench::us(p.max_ns),
                static_cast<double>(mech.voluntary) / n, static_cast<double>(mech.involuntary) / n,
                mech.failures > 0 ? "  FAILURES!" : "");
  }
  if (m.mechanisms[0].p.samples > 0 && m.mechanisms[1].p.samples > 0) {
    std::printf("ratio rack-rpc / raw futex: p50 %.2fx (target <= 1.50x: %s), p99 %.2fx\n", m.ratio_p50,
                m.ratio_p50 <= 1.5 ? "met" : "MISSED", m.ratio_p99);
  }
  std::fflush(stdout);
}

bool parse(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> const char* {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--iterations") o.iterations = std::stoull(next());
    else if (a == "--cpu-mode") o.cpu_mode = next();
    else if (a == "--json") o.json = next();
    else if (a == "--priority") o.priority = std::stoi(next());
    else if (a == "--server-cpu") o.server_cpu = std::stoi(next());
    else if (a == "--cross-cpu") o.cross_cpu = std::stoi(next());
    else if (a == "--rounds") o.rounds = std::stoi(next());
    else if (a == "--gap-us") o.gap_us = std::stoll(next());
    else if (a == "--warmup") o.warmup = std::stoull(next());
    else if (a == "--pm-qos") o.pm_qos = true;
    else if (a == "--no-diagnostics") o.diagnostics = false;
    else if (a == "--only") o.only = next();
    else if (a == "--verbose") o.verbose = true;
    else if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else throw std::invalid_argument("unknown option " + a);
  }
  if (o.cpu_mode != "same" && o.cpu_mode != "cross" && o.cpu_mode != "both") {
    throw std::invalid_argument("--cpu-mode must be same, cross or both");
  }
  if (!o.only.empty() && o.only != "futex" && o.only != "rack" && o.only != "pi_condvar" &&
      o.only != "pi_condvar_timed" && o.only != "pi_futex") {
    throw std::invalid_argument("--only must be futex, rack, pi_condvar, pi_condvar_timed or pi_futex");
  }
  if (o.only.rfind("pi_", 0) == 0) o.diagnostics = true;
  if (o.priority < 1 || o.priority > 99) throw std::invalid_argument("--priority must be 1..99");
  if (o.rounds < 1) o.rounds = 1;
  if (o.iterations < static_cast<uint64_t>(o.rounds)) o.iterations = static_cast<uint64_t>(o.rounds);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    parse(argc, argv, o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_rpc: %s\n%s", e.what(), kUsage);
    return 2;
  }
  const rt::RtCapabilities caps = rt::probe_capabilities();
  if (!caps.sched_fifo || !caps.memlock) {
    std::fprintf(stderr, "bench_rpc: needs SCHED_FIFO and mlockall (run as root): %s\n", caps.describe().c_str());
    return 1;
  }
  if (!caps.cpu_online(o.server_cpu)) {
    std::fprintf(stderr, "bench_rpc: server CPU %d is not online\n", o.server_cpu);
    return 2;
  }
  std::vector<Placement> placements;
  if (o.cpu_mode == "same" || o.cpu_mode == "both") placements.push_back({"same", o.server_cpu, o.server_cpu});
  if (o.cpu_mode == "cross" || o.cpu_mode == "both") {
    int other = o.cross_cpu;
    if (other < 0) {
      for (int c : caps.online_cpus) {
        if (c != o.server_cpu) {
          other = c;
          break;
        }
      }
    }
    if (other < 0 || other == o.server_cpu || !caps.cpu_online(other)) {
      std::fprintf(stderr, "bench_rpc: cross mode needs a second online CPU\n");
      return 2;
    }
    placements.push_back({"cross", o.server_cpu, other});
  }

  const auto mem = rt::apply_memory_policy(16u << 20);
  std::unique_ptr<rack::bench::PmQosHold> qos;
  if (o.pm_qos) {
    qos = std::make_unique<rack::bench::PmQosHold>(0);
    if (!qos->active()) std::fprintf(stderr, "bench_rpc: warning: cannot hold /dev/cpu_dma_latency\n");
  }
  const std::string load_before = rack::bench::read_first_line("/proc/loadavg");
  std::printf("bench_rpc: %s\nbench_rpc: %s; kernel %s (%s)\nbench_rpc: loadavg before: %s\n", caps.describe().c_str(),
              mem.describe().c_str(), rack::bench::kernel_string().c_str(),
              caps.preempt_rt ? "PREEMPT_RT" : "not PREEMPT_RT", load_before.c_str());

  RackSide side;
  try {
    side = start_rack(o, caps);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_rpc: cannot start the executor: %s\n", e.what());
    return 1;
  }

  std::vector<ModeResult> results;
  try {
    for (const Placement& pl : placements) {
      ModeResult mr;
      mr.placement = pl;
      mr.mechanisms.push_back({"futex", "raw futex ping-pong", {}, 0, 0, 0, {}});
      mr.mechanisms.push_back({"rack_rpc", "rack-rt GET_STATUS rpc", {}, 0, 0, 0, {}});
      if (o.diagnostics) {
        mr.mechanisms.push_back({"pi_condvar", "diag PI mutex+condvar", {}, 0, 0, 0, {}});
        mr.mechanisms.push_back({"pi_condvar_timed", "diag PI+condvar timed", {}, 0, 0, 0, {}});
        mr.mechanisms.push_back({"pi_futex", "diag PI mutex+futex", {}, 0, 0, 0, {}});
      }
      for (auto& m : mr.mechanisms) m.samples.reserve(o.iterations);
      const uint64_t per_block = o.iterations / static_cast<uint64_t>(o.rounds);
      for (int r = 0; r < o.rounds; ++r) {
        const uint64_t count = r + 1 == o.rounds ? o.iterations - per_block * static_cast<uint64_t>(r) : per_block;
        // Alternate the order so neither side always runs first.
        std::vector<std::size_t> order;
        for (std::size_t k = 0; k < mr.mechanisms.size(); ++k) order.push_back(k);
        if (r % 2 == 1) std::reverse(order.begin(), order.end());
        for (std::size_t k : order) {
          Mechanism& m = mr.mechanisms[k];
          if (!o.only.empty() && m.key != o.only && !(o.only == "rack" && m.key == "rack_rpc")) continue;
          if (m.key == "futex") m.add(run_futex_block(o, pl, count, m.samples));
          else if (m.key == "pi_condvar") m.add(run_channel_block<CondvarChannel<false>>(o, pl, count, m.samples));
          else if (m.key == "pi_condvar_timed") m.add(run_channel_block<CondvarChannel<true>>(o, pl, count, m.samples));
          else if (m.key == "pi_futex") m.add(run_channel_block<FutexChannel>(o, pl, count, m.samples));
          else m.add(run_rack_block(o, pl, side, count, m.samples));
        }
      }
      for (auto& m : mr.mechanisms) m.p = rack::bench::percentiles_of(m.samples);
      mr.ratio_p50 = mr.mechanisms[1].p.p50_ns / mr.mechanisms[0].p.p50_ns;
      mr.ratio_p99 = mr.mechanisms[1].p.p99_ns / mr.mechanisms[0].p.p99_ns;
      print_mode(mr, o);
      results.push_back(std::move(mr));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_rpc: %s\n", e.what());
    return 1;
  }
  const tims::MailboxCounters mc = side.mailbox->counters();
  const uint64_t stale = side.endpoint->stale_replies();
  side.executor->router().remove(side.mailbox->address());
  side.executor->stop();
  const std::string load_after = rack::bench::read_first_line("/proc/loadavg");
  std::printf("\nbench_rpc: loadavg after: %s; client mailbox: %llu received, %llu dropped, %llu stale replies\n",
              load_after.c_str(), static_cast<unsigned long long>(mc.received),
              static_cast<unsigned long long>(mc.dropped), static_cast<unsigned long long>(stale));

  uint64_t failures = 0;
  for (const auto& r : results) {
    for (const auto& m : r.mechanisms) failures += m.failures;
  }
  if (!o.json.empty()) {
    std::ostringstream j;
    j << "{\n  \"benchmark\": \"rpc\",\n  \"machine\": " << rack::bench::json_machine()
      << ",\n  \"iterations\": " << o.iterations << ", \"rounds\": " << o.rounds << ", \"gap_us\": " << o.gap_us
      << ", \"warmup\": " << o.warmup << ", \"priority\": " << o.priority
      << ", \"pm_qos_hold\": " << (qos && qos->active() ? "true" : "false") << ",\n  \"loadavg_before\": \""
      << load_before << "\", \"loadavg_after\": \"" << load_after
      << "\",\n  \"target_ratio_p50\": 1.5,\n  \"modes\": [";
    for (std::size_t i = 0; i < results.size(); ++i) {
      const ModeResult& r = results[i];
      j << (i ? "," : "") << "\n    {\"mode\": \"" << r.placement.mode
        << "\", \"client_cpu\": " << r.placement.client_cpu << ", \"server_cpu\": " << r.placement.server_cpu
        << ", \"ratio_p50\": " << rack::bench::json_number(r.ratio_p50)
        << ", \"ratio_p99\": " << rack::bench::json_number(r.ratio_p99) << ", \"mechanisms\": {";
      for (std::size_t k = 0; k < r.mechanisms.size(); ++k) {
        const Mechanism& m = r.mechanisms[k];
        const double n = m.p.samples > 0 ? static_cast<double>(m.p.samples) : 1.0;
        j << (k ? ", " : "") << "\n      \"" << m.key << "\": {\"latency\": " << rack::bench::json_percentiles(m.p)
          << ", \"client_voluntary_switches_per_rt\": "
          << rack::bench::json_number(static_cast<double>(m.voluntary) / n)
          << ", \"client_involuntary_switches_per_rt\": "
          << rack::bench::json_number(static_cast<double>(m.involuntary) / n) << ", \"failures\": " << m.failures
          << "}";
      }
      j << "}}";
    }
    j << "\n  ]\n}\n";
    if (!rack::bench::write_file(o.json, j.str())) {
      std::fprintf(stderr, "bench_rpc: cannot write %s\n", o.json.c_str());
      return 1;
    }
  }
  if (failures > 0) {
    std::fprintf(stderr, "bench_rpc: %llu round trips failed\n", static_cast<unsigned long long>(failures));
    return 1;
  }
  return 0;
}
