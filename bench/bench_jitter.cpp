// bench_jitter: wake-up latency of a periodic data task in a rack::Executor beside
// cyclictest (rt-tests) with the same interval, priority, CPU and duration, run one
// after the other in the same invocation (never concurrently: they would disturb
// each other). With --rounds R the duration is split into R segments per side and
// the order alternates (rack, cyclictest, cyclictest, rack, ...). Each round gives
// one ratio per percentile (that round's rack segment against its cyclictest
// segment, measured back to back under the same load); the verdict is the median of
// the per-round ratios, printed with their range, so that one noisy segment (another
// process's burst on a shared machine) cannot decide it. Targets: p99 <= 1.05x,
// p99.9 <= 1.2x cyclictest (issue 20). The pooled histograms are printed too.
//
// Both sides measure the same thing: wake-up time minus deadline on CLOCK_MONOTONIC
// after clock_nanosleep(TIMER_ABSTIME), in 1-us buckets ([i, i+1) us, truncated), and
// both skip missed periods instead of catching up. Percentiles of both come from the
// same histogram code (bench_common.h).
//
//   rack side:  a host with one Generator (period = interval, data task SCHED_FIFO
//               priority P pinned to CPU N, command task pinned there too), lcm: false,
//               memory policy applied as rackd does; after D s its data task's
//               LatencyStats histogram is read (DataComponentBase::data_task_stats()).
//               The wake-ups during the executor's start-up (the data task runs from
//               its thread's start; start() goes on with the other threads, the
//               command task's ON and the first GDOS pass) are counted apart and left
//               out, as cyclictest's own set-up comes before its first cycle
//               (--include-startup keeps them in).
//   reference:  cyclictest -m -p P -i INTERVAL -a N -t1 -q -h 10000 --secaligned PHASE
//               -l D*1e6/INTERVAL (rt-tests 2.x has no -n: clock_nanosleep is its
//               default; -l: the same number of cycles as D seconds).
//
// Phase: where a segment's deadlines fall against the kernel's 4 ms tick changes its
// latency by up to 2x on a VM (bench/RESULTS.md), and a segment that starts at a
// random moment draws a random phase: the two sides of a round would compare
// different phases. So both sides of round r put their deadlines on the same grid of
// CLOCK_MONOTONIC: whole intervals plus PHASE = (2r + 1) * INTERVAL / (2 * R) (the
// data task's `phase_ms:`, cyclictest's --secaligned), and the rounds walk the phase
// across the interval. --free-phase: each side starts where it starts, as before.
//
// Load: --load-cmd CMD runs CMD (through /bin/sh, in its own process group, normal
// scheduling) for the whole run, both sides, and stops it at the end: e.g. stress-ng,
// or a rackd running MCL at lower priority. --load-name labels it in the results.
//
// PM QoS: cyclictest holds /dev/cpu_dma_latency at 0 by default, which keeps a VM's
// CPUs polling instead of halting and cuts wake-up latency a lot; rackd does not.
// So that both sides run under the same conditions, this program holds it at 0 for
// the whole run (default), or with --no-pm-qos holds nothing and passes
// --default-system to cyclictest.
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bench_common.h"
#include "rack/components/builtin.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/rt/latency_stats.h"
#include "rack/rt/memory.h"
#include "rack/rt/modeswitch.h"

namespace {

using rack::bench::Percentiles;
namespace rt = rack::rt;

constexpr const char* kUsage =
    "usage: bench_jitter [--seconds D] [--cpu N] [--command-cpu N] [--json FILE] [--priority P] [--interval-us I]\n"
    "                    [--rounds R] [--cyclictest PATH] [--no-pm-qos] [--load-cmd CMD]\n"
    "                    [--load-name NAME] [--modeswitch] [--include-startup] [--free-phase]\n"
    "                    [--verbose]\n"
    "  --seconds D      measured seconds per side (default 30)\n"
    "  --cpu N          CPU of the periodic task on both sides (default: highest online CPU)\n"
    "  --command-cpu N  CPU of the Generator's command task (SCHED_FIFO 30, blocked while\n"
    "                   measured; default: the --cpu of the data task, as a host file that\n"
    "                   pins a component to one CPU does)\n"
    "  --json FILE      write machine-readable results (with both histograms)\n"
    "  --priority P     SCHED_FIFO priority (default 80)\n"
    "  --interval-us I  period (default 1000 = 1 kHz)\n"
    "  --rounds R       split D into R alternating segments per side (default 5); the\n"
    "                   verdict is the median of the per-round ratios\n"
    "  --cyclictest P   the cyclictest binary (default: cyclictest from PATH)\n"
    "  --no-pm-qos      do not hold /dev/cpu_dma_latency; cyclictest gets --default-system\n"
    "  --load-cmd CMD   run CMD (sh -c) as background load during both sides, e.g.\n"
    "                   'stress-ng --cpu 2 --vm 1 --vm-bytes 128M --io 1' (stopped at the end)\n"
    "  --load-name NAME the load's label in the output (default: idle, or the command)\n"
    "  --modeswitch     start mode-switch detection as rackd does (syscall user dispatch\n"
    "                   and a page-fault counter on each RT task; default: off, as an\n"
    "                   embedding program that does not start it)\n"
    "  --free-phase     do not put both sides' deadlines on the same phase of the clock in\n"
    "                   each round (default: the same phase, walked across the interval)\n"
    "  --include-startup count the RACK-RT task's wake-ups during the executor's start()\n"
    "                   (default: counted apart and left out of the figures, as cyclictest's\n"
    "                   set-up is not in its own)\n"
    "  --modeswitch-only syscalls|faults\n"
    "                   with --modeswitch: only that detector (to tell their costs apart)\n"
    "  --bare-side      a third side in every round: a bare clock_nanosleep + clock_gettime\n"
    "                   thread inside this process (same priority, CPU, phase and locked\n"
    "                   memory as RACK-RT's task, no executor running), to tell what the\n"
    "                   process costs from what the task's code costs\n"
    "  --bare-lib       --bare-side, but the bare thread sleeps and reads the clock through\n"
    "                   librack_rt (rt::sleep_until_monotonic, rt::monotonic_ns) as the\n"
    "                   data task does\n"
    "  --bare-pages N   --bare-side, and after each wake-up the bare thread writes one cache\n"
    "                   line in each of N separate 4-KiB pages (no huge pages): a cycle's\n"
    "                   page (TLB) footprint rather than its byte count\n"
    "  --bare-touch KB  --bare-side, and after each wake-up the bare thread reads and writes\n"
    "                   KB KiB of its own locked memory (a stand-in for a cycle's work), to\n"
    "                   tell how much a cycle's cache footprint moves the next wake-up\n";

constexpr double kTargetP99 = 1.05;  // issue 20: median per-round ratio
constexpr double kTargetP999 = 1.2;
constexpr std::size_t kBuckets = rt::LatencyStats::kBuckets;  // 10000 x 1 us + ">= 10 ms", like -h 10001

struct Options {
  int seconds = 30;
  int cpu = -1;
  int command_cpu = -1;  // the Generator's command task (default: --cpu)
  std::string json;
  int priority = 80;
  int interval_us = 1000;
  int rounds = 5;
  std::string cyclictest = "cyclictest";
  bool pm_qos = true;
  std::string load_cmd;
  std::string load_name;
  bool modeswitch = false;
  std::string modeswitch_only;
  bool include_startup = false;
  bool aligned = true;
  int phase_us = -1;  // this round's phase (set per round when aligned)
  bool verbose = false;
  bool bare_side = false;
  bool bare_lib = false;
  int bare_touch_kib = 0;  // --bare-touch: KiB written after each bare wake-up
  int bare_pages = 0;      // --bare-pages: 4-KiB pages (one line each) written after each bare wake-up
};

// The background load: a shell command in its own process group, so that stopping it
// stops everything it started (stress-ng forks workers; rackd has threads).
class BackgroundLoad {
 public:
  explicit BackgroundLoad(const std::string& cmd) {
    if (cmd.empty()) return;
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
    if (pid_ == 0) {
      setpgid(0, 0);
      execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    setpgid(pid_, pid_);               // also here: no race with the child's own call
    rt::sleep_for(2 * rt::kNsPerSec);  // let it ramp up before measuring
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      throw std::runtime_error("the load command exited at once (status " + std::to_string(status) + "): " + cmd);
    }
  }
  ~BackgroundLoad() {
    if (pid_ <= 0) return;
    kill(-pid_, SIGTERM);
    for (int i = 0; i < 50; ++i) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        kill(-pid_, SIGKILL);  // stragglers of the group
        return;
      }
      rt::sleep_for(100 * rt::kNsPerMs);
    }
    kill(-pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
  }
  BackgroundLoad(const BackgroundLoad&) = delete;
  BackgroundLoad& operator=(const BackgroundLoad&) = delete;
  [[nodiscard]] bool alive() const noexcept { return pid_ > 0 && waitpid(pid_, nullptr, WNOHANG) == 0; }

 private:
  pid_t pid_ = -1;
};

struct Side {
  std::string name;
  std::vector<uint64_t> histogram = std::vector<uint64_t>(kBuckets, 0);
  double max_ns = 0;       // exact where known
  uint64_t overflows = 0;  // cyclictest: latencies beyond the histogram
  uint64_t cycles = 0;
  uint64_t overruns = 0;            // rack: periods missed
  std::vector<std::string> loads;   // loadavg before/after each segment
  std::vector<Percentiles> rounds;  // each round's segment alone
  std::vector<uint64_t> late_1ms;   // each round's wake-ups >= 1 ms late
  // rack: the wake-ups during the executor's start-up, left out of the figures
  // unless --include-startup (all segments; those >= 500 us late; the worst).
  uint64_t startup_samples = 0, startup_late = 0;
  uint64_t faults_minor = 0, faults_major = 0;  // rack: the data task's, while measured
  double startup_max_ns = 0;
  Percentiles p;
};

constexpr std::size_t kLateStartupUs = 500;

// Adds a segment (measured into a fresh Side) to the totals and keeps its percentiles.
void add_segment(Side& total, const Side& seg) {
  for (std::size_t i = 0; i < kBuckets; ++i) total.histogram[i] += seg.histogram[i];
  total.max_ns = std::max(total.max_ns, seg.max_ns);
  total.overflows += seg.overflows;
  total.cycles += seg.cycles;
  total.overruns += seg.overruns;
  total.rounds.push_back(rack::bench::percentiles_of_histogram(seg.histogram, seg.max_ns));
  uint64_t late = 0;
  for (std::size_t i = 1000; i < kBuckets; ++i) late += seg.histogram[i];
  total.late_1ms.push_back(late);
  total.startup_samples += seg.startup_samples;
  total.faults_minor += seg.faults_minor;
  total.faults_major += seg.faults_major;
  total.startup_late += seg.startup_late;
  total.startup_max_ns = std::max(total.startup_max_ns, seg.startup_max_ns);
}

struct RatioStats {
  std::vector<double> per_round;
  double median = 0, min = 0, max = 0;
};

// rack / cyclictest of one percentile, round by round (a round where cyclictest's
// figure is 0 is left out: it cannot be divided by).
RatioStats ratios(const Side& rack_side, const Side& ct_side, double Percentiles::*field) {
  RatioStats r;
  for (std::size_t i = 0; i < rack_side.rounds.size() && i < ct_side.rounds.size(); ++i) {
    const double ct = ct_side.rounds[i].*field;
    if (ct > 0) r.per_round.push_back(rack_side.rounds[i].*field / ct);
  }
  if (r.per_round.empty()) return r;
  std::vector<double> v = r.per_round;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  r.median = n % 2 == 1 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2.0;
  r.min = v.front();
  r.max = v.back();
  return r;
}

// Minor and major page faults of thread `tid` of this process so far (/proc), or
// {0, 0} when it cannot be read.
std::pair<uint64_t, uint64_t> thread_faults(pid_t tid) {
  const std::string path = "/proc/self/task/" + std::to_string(tid) + "/stat";
  const std::string line = rack::bench::read_first_line(path.c_str());
  const std::size_t close = line.rfind(')');  // the name may hold spaces
  if (close == std::string::npos) return {0, 0};
  std::istringstream in(line.substr(close + 2));
  std::string field;
  uint64_t minor = 0, major = 0;
  // After the name: state ppid pgrp session tty_nr tpgid flags minflt cminflt majflt
  for (int i = 1; i <= 10 && in >> field; ++i) {
    if (i == 8) minor = std::strtoull(field.c_str(), nullptr, 10);
    if (i == 10) major = std::strtoull(field.c_str(), nullptr, 10);
  }
  return {minor, major};
}

std::string host_text(const Options& o) {
  std::ostringstream y;
  y << "host: bench-jitter\n"
       "system: 0\n"
       "host_id: 0\n"
       "lcm: false\n"
       "heap_prefault_mib: 16\n"
       "components:\n"
       "  - name: gen\n"
       "    class: Generator\n"
       "    instance: 0\n"
       "    autostart: true\n"
       "    command_task: {priority: 30, cpu: "
    << (o.command_cpu >= 0 ? o.command_cpu : o.cpu)
    << "}\n"
       "    data_task: {priority: "
    << o.priority << ", cpu: " << o.cpu << ", period_ms: " << static_cast<double>(o.interval_us) / 1000.0;
  if (o.phase_us >= 0) y << ", phase_ms: " << static_cast<double>(o.phase_us) / 1000.0;
  y << "}\n";
  return y.str();
}

void run_rack_segment(const Options& o, const rt::RtCapabilities& caps, int seconds, Side& side) {
  rack::ComponentRegistry registry;
  rack::components::register_builtin(registry);
  auto loaded = rack::load_host_text(host_text(o), "bench_jitter.yaml", registry, caps);
  if (!loaded.errors.empty()) {
    std::string all;
    for (const auto& e : loaded.errors) all += e.str() + "\n";
    throw std::runtime_error("host text rejected:\n" + all);
  }
  rack::ExecutorOptions eo;
  eo.allow_rt_fallback = false;
  const bool verbose = o.verbose;
  eo.log = [verbose](const std::string& line) {
    if (verbose) std::fprintf(stderr, "rackd: %s\n", line.c_str());
  };
  rack::Executor executor(std::move(loaded.host), eo);
  executor.start();
  auto* gen = dynamic_cast<rack::DataComponentBase*>(executor.find("gen"));
  if (gen == nullptr) throw std::runtime_error("component 'gen' not found");
  if (gen->state() != rack::ComponentState::kEnabled) {
    throw std::runtime_error("the Generator did not switch on");
  }
  // The start-up's wake-ups: from the data task's first cycle until start() returned.
  auto before = std::make_unique<std::array<uint64_t, kBuckets>>();
  gen->data_task_stats().copy_histogram(*before);
  const rt::LatencySummary s0 = gen->data_task_stats().summary();
  const pid_t data_tid = gen->data_task_faults().tid();
  const auto faults0 = thread_faults(data_tid);
  rt::sleep_for(static_cast<int64_t>(seconds) * rt::kNsPerSec);
  const auto faults1 = thread_faults(data_tid);
  side.faults_minor += faults1.first - faults0.first;
  side.faults_major += faults1.second - faults0.second;
  auto hist = std::make_unique<std::array<uint64_t, kBuckets>>();
  // Read while the task still runs: a snapshot a sample or two old is fine.
  gen->data_task_stats().copy_histogram(*hist);
  const rt::LatencySummary s = gen->data_task_stats().summary();
  executor.stop();
  std::size_t top = 0, top_before = 0;  // highest non-empty bucket + 1
  for (std::size_t i = 0; i < kBuckets; ++i) {
    side.startup_samples += (*before)[i];
    if (i >= kLateStartupUs) side.startup_late += (*before)[i];
    if ((*before)[i] > 0) top_before = i + 1;
    if (!o.include_startup) (*hist)[i] -= (*before)[i];
    side.histogram[i] += (*hist)[i];
    if ((*hist)[i] > 0) top = i + 1;
  }
  side.startup_max_ns = static_cast<double>(top_before) * 1000.0;
  // The exact maximum is the segment's when it fell after the start-up; otherwise the
  // top bucket's upper edge.
  const bool exact = o.include_startup || top >= top_before;
  side.max_ns = std::max(side.max_ns, exact ? static_cast<double>(s.max_ns) : static_cast<double>(top) * 1000.0);
  side.cycles += o.include_startup ? s.cycles : s.cycles - s0.cycles;
  side.overruns += o.include_startup ? s.overruns : s.overruns - s0.overruns;
  if (executor.any_fallback()) throw std::runtime_error("SCHED_FIFO was refused");
}

// The bare side: what cyclictest's loop does, in a thread of this process (its memory
// locked and its libraries mapped as for the RACK-RT side, but no executor running).
// If this side lies with cyclictest, a gap is the task's code; if with RACK-RT's task,
// it is the process.
void run_bare_segment(const Options& o, int seconds, Side& side) {
  struct Ctx {
    const Options* o;
    int seconds;
    Side* side;
    std::string error;
    unsigned char* touch;  // --bare-touch: written after each wake-up (nullptr: none)
    std::size_t touch_bytes;
    unsigned char* pages;  // --bare-pages: one line of each page written after each wake-up
    std::size_t page_count;
  };
  // Allocated and written here, before the thread starts (memory is locked: no fault later).
  std::vector<unsigned char> touch(static_cast<std::size_t>(o.bare_touch_kib) * 1024, 1);
  // --bare-pages: small pages on purpose (no transparent huge page), so that each one
  // needs its own TLB entry: a cycle's page footprint, not its byte count.
  const std::size_t page_count = static_cast<std::size_t>(o.bare_pages);
  void* pages = MAP_FAILED;
  if (page_count > 0) {
    pages = mmap(nullptr, page_count * 4096, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (pages == MAP_FAILED) throw std::runtime_error("--bare-pages: mmap failed");
    (void)madvise(pages, page_count * 4096, MADV_NOHUGEPAGE);
    std::memset(pages, 1, page_count * 4096);
  }
  Ctx ctx{&o,
          seconds,
          &side,
          {},
          touch.empty() ? nullptr : touch.data(),
          touch.size(),
          page_count > 0 ? static_cast<unsigned char*>(pages) : nullptr,
          page_count};
  auto body = [](void* arg) -> void* {
    auto& c = *static_cast<Ctx*>(arg);
    const int64_t period = static_cast<int64_t>(c.o->interval_us) * rt::kNsPerUs;
    int64_t now = rt::monotonic_ns();
    int64_t next = now + period;
    if (c.o->phase_us >= 0) {
      const int64_t phase = static_cast<int64_t>(c.o->phase_us) * rt::kNsPerUs;
      next = (now - phase) / period * period + phase + period;
    }
    const int64_t end = now + static_cast<int64_t>(c.seconds) * rt::kNsPerSec;
    uint64_t* h = c.side->histogram.data();
    int64_t max_ns = 0;
    while (next < end) {
      timespec woke{};
      if (c.o->bare_lib) {  // the library's sleep and clock, as the data task calls them
        woke = rt::to_timespec(rt::sleep_until_monotonic(next));
      } else {
        const timespec ts = rt::to_timespec(next);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
        }
        clock_gettime(CLOCK_MONOTONIC, &woke);
      }
      const int64_t lat = std::max<int64_t>(0, rt::from_timespec(woke) - next);
      max_ns = std::max(max_ns, lat);
      h[std::min<std::size_t>(static_cast<std::size_t>(lat / rt::kNsPerUs), kBuckets - 1)] += 1;
      c.side->cycles += 1;
      // A cycle's work stand-in: one read-modify-write per cache line of the buffer.
      for (std::size_t i = 0; i < c.touch_bytes; i += 64) {
        c.touch[i] = static_cast<unsigned char>(c.touch[i] + 1);
      }
      for (std::size_t i = 0; i < c.page_count; ++i) {  // a line at a different offset in each page
        unsigned char& b = c.pages[i * 4096 + (i % 64) * 64];
        b = static_cast<unsigned char>(b + 1);
      }
      asm volatile("" ::: "memory");  // the stores are the point: keep them
      next += period;
      now = rt::from_timespec(woke);
      if (now >= next) next += ((now - next) / period + 1) * period;  // skip missed periods, like cyclictest
    }
    c.side->max_ns = static_cast<double>(max_ns);
    return nullptr;
  };
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
  pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
  sched_param sp{};
  sp.sched_priority = o.priority;
  pthread_attr_setschedparam(&attr, &sp);
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(o.cpu), &set);
  pthread_attr_setaffinity_np(&attr, sizeof set, &set);
  pthread_t th{};
  const int rc = pthread_create(&th, &attr, body, &ctx);
  pthread_attr_destroy(&attr);
  if (rc == 0) pthread_join(th, nullptr);
  if (pages != MAP_FAILED) munmap(pages, page_count * 4096);
  if (rc != 0) throw std::runtime_error(std::string("bare side: pthread_create: ") + std::strerror(rc));
}

// Runs cyclictest and adds its histogram to `side`.
void run_cyclictest_segment(const Options& o, int seconds, Side& side) {
  std::ostringstream cmd;
  cmd << o.cyclictest << " -m -p " << o.priority << " -i " << o.interval_us << " -a " << o.cpu << " -t1";
  if (o.phase_us >= 0) {  // the same grid as the data task's phase_ms; as many cycles as D seconds
    cmd << " --secaligned " << o.phase_us << " -l " << static_cast<long long>(seconds) * 1'000'000LL / o.interval_us;
  } else {
    cmd << " -D " << seconds << "s";
  }
  cmd << " -q -h " << kBuckets << (o.pm_qos ? "" : " --default-system") << " 2>&1";
  if (o.verbose) std::fprintf(stderr, "bench_jitter: %s\n", cmd.str().c_str());
  FILE* pipe = popen(cmd.str().c_str(), "r");
  if (pipe == nullptr) throw std::runtime_error("cannot run " + cmd.str());
  char line[512];
  std::string unparsed;
  uint64_t total = 0, counted = 0;
  while (std::fgets(line, sizeof line, pipe) != nullptr) {
    unsigned long long bucket = 0, count = 0;
    if (std::sscanf(line, "%llu %llu", &bucket, &count) == 2 && line[0] != '#') {
      if (bucket < kBuckets) side.histogram[bucket] += count;
      counted += count;
      continue;
    }
    if (std::sscanf(line, "# Total: %llu", &count) == 1) {
      total += count;
      continue;
    }
    if (std::sscanf(line, "# Max Latencies: %llu", &count) == 1) {
      side.max_ns = std::max(side.max_ns, static_cast<double>(count) * 1000.0);
      continue;
    }
    if (std::sscanf(line, "# Histogram Overflows: %llu", &count) == 1) {
      side.overflows += count;
      continue;
    }
    if (line[0] != '#') unparsed += line;
  }
  const int status = pclose(pipe);
  if (status != 0 || total == 0) {
    throw std::runtime_error("cyclictest failed (status " + std::to_string(status) + "): " + cmd.str() + "\n" +
                             unparsed);
  }
  // Overflows (>= kBuckets us) go to the last bucket, as LatencyStats does.
  side.histogram[kBuckets - 1] += side.overflows;
  side.cycles += total;
  (void)counted;
}

// A coarse side-by-side view of both histograms.
void print_coarse(const Side& a, const Side& b) {
  const int edges[] = {0, 5, 10, 20, 30, 50, 100, 200, 500, 1000, 2000, 5000, static_cast<int>(kBuckets)};
  std::printf("%-18s %14s %14s\n", "latency (us)", a.name.c_str(), b.name.c_str());
  for (std::size_t k = 0; k + 1 < std::size(edges); ++k) {
    uint64_t ca = 0, cb = 0;
    for (int i = edges[k]; i < edges[k + 1]; ++i) {
      ca += a.histogram[static_cast<std::size_t>(i)];
      cb += b.histogram[static_cast<std::size_t>(i)];
    }
    char label[32];
    if (k + 2 == std::size(edges)) std::snprintf(label, sizeof label, ">= %d", edges[k]);
    else std::snprintf(label, sizeof label, "[%d, %d)", edges[k], edges[k + 1]);
    std::printf("%-18s %14llu %14llu\n", label, static_cast<unsigned long long>(ca),
                static_cast<unsigned long long>(cb));
  }
}

std::string json_histogram(const std::vector<uint64_t>& h) {
  std::ostringstream o;
  o << "[";
  bool first = true;
  for (std::size_t i = 0; i < h.size(); ++i) {
    if (h[i] == 0) continue;
    o << (first ? "" : ", ") << "[" << i << ", " << h[i] << "]";
    first = false;
  }
  o << "]";
  return o.str();
}

void parse(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> const char* {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--seconds") o.seconds = std::stoi(next());
    else if (a == "--cpu") o.cpu = std::stoi(next());
    else if (a == "--command-cpu") o.command_cpu = std::stoi(next());
    else if (a == "--json") o.json = next();
    else if (a == "--priority") o.priority = std::stoi(next());
    else if (a == "--interval-us") o.interval_us = std::stoi(next());
    else if (a == "--rounds") o.rounds = std::stoi(next());
    else if (a == "--cyclictest") o.cyclictest = next();
    else if (a == "--no-pm-qos") o.pm_qos = false;
    else if (a == "--load-cmd") o.load_cmd = next();
    else if (a == "--load-name") o.load_name = next();
    else if (a == "--verbose") o.verbose = true;
    else if (a == "--modeswitch") o.modeswitch = true;
    else if (a == "--include-startup") o.include_startup = true;
    else if (a == "--bare-side") o.bare_side = true;
    else if (a == "--bare-lib") o.bare_side = o.bare_lib = true;
    else if (a == "--bare-touch") {
      o.bare_side = true;
      o.bare_touch_kib = std::stoi(next());
      if (o.bare_touch_kib < 0 || o.bare_touch_kib > 65536)
        throw std::invalid_argument("--bare-touch takes 0..65536 KiB");
    } else if (a == "--bare-pages") {
      o.bare_side = true;
      o.bare_pages = std::stoi(next());
      if (o.bare_pages < 0 || o.bare_pages > 65536) throw std::invalid_argument("--bare-pages takes 0..65536 pages");
    } else if (a == "--free-phase") o.aligned = false;
    else if (a == "--modeswitch-only") {
      o.modeswitch_only = next();
      if (o.modeswitch_only != "syscalls" && o.modeswitch_only != "faults") {
        throw std::invalid_argument("--modeswitch-only takes syscalls or faults");
      }
    } else if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else throw std::invalid_argument("unknown option " + a);
  }
  if (o.seconds < 1) throw std::invalid_argument("--seconds must be >= 1");
  if (o.priority < 1 || o.priority > 99) throw std::invalid_argument("--priority must be 1..99");
  if (o.interval_us < 50) throw std::invalid_argument("--interval-us must be >= 50");
  if (o.load_name.empty()) o.load_name = o.load_cmd.empty() ? "idle" : o.load_cmd;
  if (o.rounds < 1) o.rounds = 1;
  if (o.rounds > o.seconds) o.rounds = o.seconds;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  std::string command_line;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool quote = arg.find_first_of(" '\"") != std::string::npos;
    command_line += (i ? " " : "") + (quote ? "'" + arg + "'" : arg);
  }
  try {
    parse(argc, argv, o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_jitter: %s\n%s", e.what(), kUsage);
    return 2;
  }
  const rt::RtCapabilities caps = rt::probe_capabilities();
  if (!caps.sched_fifo || !caps.memlock) {
    std::fprintf(stderr, "bench_jitter: needs SCHED_FIFO and mlockall (run as root): %s\n", caps.describe().c_str());
    return 1;
  }
  if (o.cpu < 0) o.cpu = caps.online_cpus.empty() ? 0 : caps.online_cpus.back();
  if (!caps.cpu_online(o.cpu)) {
    std::fprintf(stderr, "bench_jitter: CPU %d is not online\n", o.cpu);
    return 2;
  }
  const auto mem = rt::apply_memory_policy(16u << 20);
  std::unique_ptr<rack::bench::PmQosHold> qos;
  if (o.pm_qos) {
    qos = std::make_unique<rack::bench::PmQosHold>(0);
    if (!qos->active()) std::fprintf(stderr, "bench_jitter: warning: cannot hold /dev/cpu_dma_latency at 0\n");
  }
  if (o.modeswitch) {
    rt::modeswitch::Config mc;
    mc.program = "bench_jitter";
    mc.crash_handlers = false;
    if (!o.modeswitch_only.empty()) {
      mc.syscalls = o.modeswitch_only == "syscalls";
      mc.faults = o.modeswitch_only == "faults";
      mc.allocations = false;
      mc.locks = false;
    }
    std::printf("bench_jitter: %s\n", rt::modeswitch::start(mc).describe().c_str());
  }
  const std::string load_before = rack::bench::read_first_line("/proc/loadavg");
  std::printf("bench_jitter: %s\nbench_jitter: %s; kernel %s (%s)\nbench_jitter: loadavg before: %s\n",
              caps.describe().c_str(), mem.describe().c_str(), rack::bench::kernel_string().c_str(),
              caps.preempt_rt ? "PREEMPT_RT" : "not PREEMPT_RT", load_before.c_str());

  const int seg = o.seconds / o.rounds;
  const int last = o.seconds - seg * (o.rounds - 1);
  Side rack_side;
  rack_side.name = "rack-rt";
  Side ct_side;
  ct_side.name = "cyclictest";
  Side bare_side;
  bare_side.name = "bare";
  std::printf("bench_jitter: %d s per side on CPU %d, SCHED_FIFO %d, interval %d us, %d round(s), PM QoS %s\n",
              o.seconds, o.cpu, o.priority, o.interval_us, o.rounds,
              qos && qos->active() ? "held at 0 us" : "not held (cyclictest --default-system)");
  std::printf("bench_jitter: mode-switch detection %s\n", o.modeswitch ? "on (as rackd)" : "off");
  std::printf("bench_jitter: RACK-RT's command task (SCHED_FIFO 30, blocked while measured) on CPU %d\n",
              o.command_cpu >= 0 ? o.command_cpu : o.cpu);
  std::printf("bench_jitter: phase: %s\n", o.aligned ? "both sides of a round on the same grid of the clock "
                                                       "(phase_ms / --secaligned), walked across the interval"
                                                     : "free (--free-phase: each segment where it starts)");
  std::printf("bench_jitter: RACK-RT's wake-ups during the executor's start-up %s\n",
              o.include_startup ? "included (--include-startup)" : "counted apart, not in the figures");
  std::printf("bench_jitter: load: %s%s%s\n", o.load_name.c_str(), o.load_cmd.empty() ? "" : " = ", o.load_cmd.c_str());
  std::fflush(stdout);
  bool load_survived = true;
  std::vector<int> phases;  // per round, us (-1: free)
  try {
    BackgroundLoad load(o.load_cmd);
    for (int r = 0; r < o.rounds; ++r) {
      const int secs = r + 1 == o.rounds ? last : seg;
      if (o.aligned) o.phase_us = (2 * r + 1) * o.interval_us / (2 * o.rounds);
      phases.push_back(o.phase_us);
      const int sides = o.bare_side ? 3 : 2;
      for (int k = 0; k < sides; ++k) {
        // rack, ct, ct, rack, rack, ct, ...; with --bare-side the bare thread in the middle
        const bool bare_now = o.bare_side && k == 1;
        const int kk = o.bare_side && k == 2 ? 1 : k;
        const bool rack_now = !bare_now && (kk == 0) == (r % 2 == 0);
        Side& side = bare_now ? bare_side : rack_now ? rack_side : ct_side;
        side.loads.push_back(rack::bench::read_first_line("/proc/loadavg"));
        std::printf("bench_jitter: round %d: %s for %d s, phase %s (loadavg %s)\n", r + 1, side.name.c_str(), secs,
                    o.phase_us >= 0 ? (std::to_string(o.phase_us) + " us").c_str() : "free", side.loads.back().c_str());
        std::fflush(stdout);
        Side segment;
        if (bare_now) run_bare_segment(o, secs, segment);
        else if (rack_now) run_rack_segment(o, caps, secs, segment);
        else run_cyclictest_segment(o, secs, segment);
        add_segment(side, segment);
        side.loads.push_back(rack::bench::read_first_line("/proc/loadavg"));
      }
    }
    load_survived = o.load_cmd.empty() || load.alive();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_jitter: %s\n", e.what());
    return 1;
  }
  if (!load_survived) {
    std::fprintf(stderr, "bench_jitter: the load command ended before the measurement did: %s\n", o.load_cmd.c_str());
    return 1;
  }
  if (o.modeswitch) rt::modeswitch::stop();
  rack_side.p = rack::bench::percentiles_of_histogram(rack_side.histogram, rack_side.max_ns);
  bare_side.p = rack::bench::percentiles_of_histogram(bare_side.histogram, bare_side.max_ns);
  ct_side.p = rack::bench::percentiles_of_histogram(ct_side.histogram, ct_side.max_ns);
  const RatioStats r99 = ratios(rack_side, ct_side, &Percentiles::p99_ns);
  const RatioStats r999 = ratios(rack_side, ct_side, &Percentiles::p999_ns);
  const RatioStats r50 = ratios(rack_side, ct_side, &Percentiles::p50_ns);
  const double ratio_p99 = ct_side.p.p99_ns > 0 ? rack_side.p.p99_ns / ct_side.p.p99_ns : 0.0;
  const double ratio_p999 = ct_side.p.p999_ns > 0 ? rack_side.p.p999_ns / ct_side.p.p999_ns : 0.0;
  const double ratio_p50 = ct_side.p.p50_ns > 0 ? rack_side.p.p50_ns / ct_side.p.p50_ns : 0.0;
  const std::string load_after = rack::bench::read_first_line("/proc/loadavg");

  std::printf("\n== wake-up latency, %d us period, SCHED_FIFO %d, CPU %d, %d s each, load: %s ==\n", o.interval_us,
              o.priority, o.cpu, o.seconds, o.load_name.c_str());
  std::printf("%-12s %10s %8s %8s %8s %8s %8s %10s %9s\n", "side (us)", "samples", "min", "p50", "p99", "p99.9", "max",
              "mean", "overruns");
  std::vector<const Side*> shown{&rack_side, &ct_side};
  if (o.bare_side) shown.push_back(&bare_side);
  for (const Side* s : shown) {
    std::printf("%-12s %10llu %8.0f %8.0f %8.0f %8.0f %8.1f %10.1f %9llu\n", s->name.c_str(),
                static_cast<unsigned long long>(s->p.samples), rack::bench::us(s->p.min_ns),
                rack::bench::us(s->p.p50_ns), rack::bench::us(s->p.p99_ns), rack::bench::us(s->p.p999_ns),
                rack::bench::us(s->p.max_ns), rack::bench::us(s->p.mean_ns),
                static_cast<unsigned long long>(s == &rack_side ? s->overruns : s->overflows));
  }
  std::printf(
      "(percentiles in whole us, truncated like cyclictest; cyclictest's last column counts "
      "histogram overflows, rack's counts missed periods)\n");
  std::printf("pooled ratio rack-rt / cyclictest: p50 %.2fx, p99 %.2fx, p99.9 %.2fx\n", ratio_p50, ratio_p99,
              ratio_p999);
  std::printf(
      "per round (rack p99 / p99.9 vs cyclictest p99 / p99.9, us; wake-ups >= 1 ms late, rack vs cyclictest):\n");
  for (std::size_t i = 0; i < rack_side.rounds.size() && i < ct_side.rounds.size(); ++i) {
    const Percentiles& a = rack_side.rounds[i];
    const Percentiles& b = ct_side.rounds[i];
    std::printf(
        "  round %zu (phase %4d us): %4.0f / %4.0f vs %4.0f / %4.0f  -> p99 %.2fx, p99.9 %.2fx; >= 1 ms: %llu vs %llu\n",
        i + 1, i < phases.size() ? phases[i] : -1, rack::bench::us(a.p99_ns), rack::bench::us(a.p999_ns),
        rack::bench::us(b.p99_ns), rack::bench::us(b.p999_ns), b.p99_ns > 0 ? a.p99_ns / b.p99_ns : 0.0,
        b.p999_ns > 0 ? a.p999_ns / b.p999_ns : 0.0, static_cast<unsigned long long>(rack_side.late_1ms[i]),
        static_cast<unsigned long long>(ct_side.late_1ms[i]));
  }
  std::printf(
      "rack-rt start-up (data task's first cycle to start() returning, all rounds): %llu wake-ups, %llu of "
      "them >= %zu us late, worst < %.0f us; %s\n",
      static_cast<unsigned long long>(rack_side.startup_samples),
      static_cast<unsigned long long>(rack_side.startup_late), kLateStartupUs,
      rack::bench::us(rack_side.startup_max_ns),
      o.include_startup ? "included in the figures above" : "not in the figures above");
  std::printf("rack-rt data task page faults while measured (all rounds, /proc): %llu minor, %llu major\n",
              static_cast<unsigned long long>(rack_side.faults_minor),
              static_cast<unsigned long long>(rack_side.faults_major));
  std::printf(
      "median of %zu per-round ratios: p99 %.2fx (range %.2f-%.2f; target <= %.2fx: %s), "
      "p99.9 %.2fx (range %.2f-%.2f; target <= %.2fx: %s), p50 %.2fx\n\n",
      r99.per_round.size(), r99.median, r99.min, r99.max, kTargetP99, r99.median <= kTargetP99 ? "met" : "MISSED",
      r999.median, r999.min, r999.max, kTargetP999, r999.median <= kTargetP999 ? "met" : "MISSED", r50.median);
  print_coarse(rack_side, ct_side);
  if (o.bare_side) {
    const RatioStats b99 = ratios(bare_side, ct_side, &Percentiles::p99_ns);
    const RatioStats b50 = ratios(bare_side, ct_side, &Percentiles::p50_ns);
    const RatioStats rb99 = ratios(rack_side, bare_side, &Percentiles::p99_ns);
    std::printf(
        "bare side (cyclictest's loop in this process): median per-round ratio bare / cyclictest p50 %.2fx, "
        "p99 %.2fx (range %.2f-%.2f); rack-rt / bare p99 %.2fx (range %.2f-%.2f); means rack-rt %.1f, bare %.1f, "
        "cyclictest %.1f us\n",
        b50.median, b99.median, b99.min, b99.max, rb99.median, rb99.min, rb99.max, rack::bench::us(rack_side.p.mean_ns),
        rack::bench::us(bare_side.p.mean_ns), rack::bench::us(ct_side.p.mean_ns));
    print_coarse(bare_side, ct_side);
  }
  std::printf("bench_jitter: loadavg after: %s\n", load_after.c_str());

  if (!o.json.empty()) {
    std::ostringstream j;
    j << "{\n  \"benchmark\": \"jitter\",\n  \"command\": \"" << rack::bench::json_escape(command_line)
      << "\",\n  \"machine\": " << rack::bench::json_machine() << ",\n  \"seconds\": " << o.seconds
      << ", \"cpu\": " << o.cpu << ", \"command_cpu\": " << (o.command_cpu >= 0 ? o.command_cpu : o.cpu)
      << ", \"priority\": " << o.priority << ", \"interval_us\": " << o.interval_us << ", \"rounds\": " << o.rounds
      << ", \"load_name\": \"" << rack::bench::json_escape(o.load_name) << "\", \"load_cmd\": \""
      << rack::bench::json_escape(o.load_cmd) << "\", \"modeswitch\": " << (o.modeswitch ? "true" : "false")
      << ", \"include_startup\": " << (o.include_startup ? "true" : "false")
      << ", \"aligned\": " << (o.aligned ? "true" : "false") << ", \"phase_us\": [";
    for (std::size_t i = 0; i < phases.size(); ++i) j << (i ? ", " : "") << phases[i];
    j << "]"
      << ", \"startup\": {\"samples\": " << rack_side.startup_samples << ", \"late_500us\": " << rack_side.startup_late
      << ", \"max_us_below\": " << rack::bench::json_number(rack::bench::us(rack_side.startup_max_ns))
      << "}, \"data_task_faults\": {\"minor\": " << rack_side.faults_minor << ", \"major\": " << rack_side.faults_major
      << "}"
      << ", \"pm_qos_hold\": " << (qos && qos->active() ? "true" : "false") << ",\n  \"loadavg_before\": \""
      << load_before << "\", \"loadavg_after\": \"" << load_after << "\",\n  \"target_ratio_p99\": " << kTargetP99
      << ", \"target_ratio_p999\": " << kTargetP999 << ", \"ratio_p99\": " << rack::bench::json_number(ratio_p99)
      << ", \"ratio_p999\": " << rack::bench::json_number(ratio_p999)
      << ", \"ratio_p50\": " << rack::bench::json_number(ratio_p50) << ",\n  \"round_ratios\": {";
    bool first_ratio = true;
    for (const auto& [name, rs] : {std::pair{"p50", &r50}, std::pair{"p99", &r99}, std::pair{"p999", &r999}}) {
      j << (first_ratio ? "" : ", ") << "\"" << name << "\": {\"median\": " << rack::bench::json_number(rs->median)
        << ", \"min\": " << rack::bench::json_number(rs->min) << ", \"max\": " << rack::bench::json_number(rs->max)
        << ", \"per_round\": [";
      for (std::size_t i = 0; i < rs->per_round.size(); ++i) {
        j << (i ? ", " : "") << rack::bench::json_number(rs->per_round[i]);
      }
      j << "]}";
      first_ratio = false;
    }
    j << "}"
      << ",\n  \"sides\": {";
    bool first = true;
    for (const Side* s : {&rack_side, &ct_side}) {
      j << (first ? "" : ",") << "\n    \"" << (s == &rack_side ? "rack" : "cyclictest")
        << "\": {\"latency\": " << rack::bench::json_percentiles(s->p) << ", \"cycles\": " << s->cycles
        << ", \"overruns\": " << s->overruns << ", \"histogram_overflows\": " << s->overflows << ", \"late_1ms\": [";
      for (std::size_t i = 0; i < s->late_1ms.size(); ++i) j << (i ? ", " : "") << s->late_1ms[i];
      j << "], \"rounds\": [";
      for (std::size_t i = 0; i < s->rounds.size(); ++i) {
        j << (i ? ", " : "") << rack::bench::json_percentiles(s->rounds[i]);
      }
      j << "], \"loadavg\": [";
      for (std::size_t i = 0; i < s->loads.size(); ++i) j << (i ? ", " : "") << "\"" << s->loads[i] << "\"";
      j << "],\n      \"histogram_us\": " << json_histogram(s->histogram) << "}";
      first = false;
    }
    j << "\n  }\n}\n";
    if (!rack::bench::write_file(o.json, j.str())) {
      std::fprintf(stderr, "bench_jitter: cannot write %s\n", o.json.c_str());
      return 1;
    }
  }
  return 0;
}
