// bench_lcm: TiMS between two hosts over LCM, beside raw LCM on the same URL in the
// same run. The two "hosts" are two network namespaces joined by a veth pair (MTU
// 1500, as Ethernet), made by this program and deleted at its end; each side's LCM
// sockets are created by a thread that entered its namespace.
//
//   rpc:  round trip of tims::Endpoint::call(GET_STATUS) from a tool endpoint in host A
//         to a Generator's command task in a rack::Executor in host B (TiMS/LCM both
//         ways, through the transports' sender and receive threads), beside
//         reference "lcm-ping": a 64-byte LCM message from A, echoed by a plain LCM
//         handler in B (the shortest path LCM itself offers). Blocks alternate.
//   bulk: 100 KB and 1 MB messages from A to B as fast as the sender is allowed,
//         TiMS (chunked by the transport; optionally zstd on the link) beside raw LCM
//         publish() of the same sizes (LCM fragments them itself). Reported:
//         throughput of what arrived and the fraction lost.
//
// Needs root (namespaces). Not RT code; no SCHED_FIFO for the measuring threads (both
// mechanisms run their LCM threads at normal priority alike).
#include <dirent.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <iomanip>
#include <map>
#include <zstd.h>

#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <mutex>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "rack/components/builtin.h"
#include "rack/components/class_ids.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/lcm_transport.h"

namespace {

using rack::bench::Percentiles;
namespace rt = rack::rt;
namespace tims = rack::tims;

constexpr const char* kUsage =
    "usage: bench_lcm [--iterations N] [--rounds R] [--bulk-count N] [--bulk-rounds R] [--port P]\n"
    "                 [--cpus A,B|any] [--json FILE] [--quick] [--no-rpc] [--bulk LIST] [--bulk-queue Q]\n"
    "                 [--cpu-report]\n"
    "  --iterations N   timed round trips per mechanism (default 4000)\n"
    "  --rounds R       alternate the two RPC mechanisms in R blocks (default 4)\n"
    "  --bulk-count N   bulk messages per size, mechanism and round (default 400 of 100 KB;\n"
    "                   1 MB: N/4)\n"
    "  --bulk-rounds R  alternate the bulk mechanisms in R rounds (default 3)\n"
    "  --bulk-queue Q   TiMS bulk sender keeps at most Q messages queued in the uplink,\n"
    "                   refilled when Q/3 are left (1-7, default 6); raw LCM's publish()\n"
    "                   blocks in the kernel instead\n"
    "  --port P         LCM port (default 7790); URL udpm://239.255.76.67:P?ttl=1&recv_buf_size=4194304\n"
    "  --cpus A,B       CPU of host A's and of host B's threads (default 0,1: one CPU per\n"
    "                   computer); any: not pinned\n"
    "  --json FILE      machine-readable results\n"
    "  --quick          1000 round trips, 2 rounds; 100 bulk messages, 2 bulk rounds\n"
    "  --no-rpc         bulk only\n"
    "  --bulk LIST      bulk mechanisms, comma-separated: lcm, tims, lcm+zstd, tims+zstd,\n"
    "                   zstd (both compressed ones); default lcm,tims,zstd (all four)\n"
    "  --cpu-report     per bulk run: CPU busy per CPU and this process's CPU time per\n"
    "                   thread and MB (where the time goes)\n";

struct Options {
  int iterations = 4000;
  int rounds = 4;
  int bulk_count = 400;
  int bulk_rounds = 3;
  int bulk_queue = 6;  // TiMS bulk sender: most messages queued in the uplink
  int port = 7790;
  int cpu_a = 0;  // -1: not pinned
  int cpu_b = 1;
  std::string json;
  bool rpc = true;
  bool cpu_report = false;
  std::string bulk = "lcm,tims,zstd";  // which bulk mechanisms run (diagnosis: one at a time)
};

int sh(const std::string& cmd) { return std::system((cmd + " >/dev/null 2>&1").c_str()); }

// Two namespaces on a veth pair; deleted by the destructor.
struct Namespaces {
  std::string a, b;
  Namespaces() {
    const std::string p = "rkbench-" + std::to_string(getpid());
    a = p + "-a";
    b = p + "-b";
    const std::vector<std::string> cmds = {"ip netns add " + a,
                                           "ip netns add " + b,
                                           "ip link add eth0 netns " + a + " type veth peer name eth0 netns " + b,
                                           "ip -n " + a + " link set lo up",
                                           "ip -n " + b + " link set lo up",
                                           "ip -n " + a + " addr add 10.78.0.1/24 dev eth0",
                                           "ip -n " + b + " addr add 10.78.0.2/24 dev eth0",
                                           "ip -n " + a + " link set eth0 up",
                                           "ip -n " + b + " link set eth0 up",
                                           "ip -n " + a + " route add 224.0.0.0/4 dev eth0",
                                           "ip -n " + b + " route add 224.0.0.0/4 dev eth0"};
    for (const auto& c : cmds) {
      if (sh(c) != 0) {
        cleanup();
        throw std::runtime_error("'" + c + "' failed (root and iproute2 needed)");
      }
    }
  }
  ~Namespaces() { cleanup(); }
  void cleanup() {
    sh("ip netns del " + a);
    sh("ip netns del " + b);
  }
};

void enter(const std::string& ns) {
  const std::string path = "/run/netns/" + ns;
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || setns(fd, CLONE_NEWNET) != 0) throw std::runtime_error("cannot enter " + path);
  close(fd);
}

// Pins the calling thread (and every thread it creates later) to one CPU.
void pin(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(cpu), &set);
  if (sched_setaffinity(0, sizeof set, &set) != 0) throw std::runtime_error("cannot pin to CPU " + std::to_string(cpu));
}

// Runs `fn` on a thread inside namespace `ns`, pinned to `cpu`, and waits for it:
// objects made there keep their sockets in that namespace, and the threads they start
// (transport, executor tasks, LCM's own) stay on that CPU, as on a computer of its own.
void in_ns(const std::string& ns, int cpu, const std::function<void()>& fn) {
  std::exception_ptr err;
  std::thread t([&] {
    try {
      // Threads made here (LCM's own) inherit the name: "A"/"B" + what follows.
      pthread_setname_np(pthread_self(), (ns.substr(ns.size() - 1) == "a" ? "A-lcm" : "B-lcm"));
      if (cpu >= 0) pin(cpu);
      enter(ns);
      fn();
    } catch (...) {
      err = std::current_exception();
    }
  });
  t.join();
  if (err) std::rethrow_exception(err);
}

// ---------------------------------------------------------------- CPU accounting
// Where the CPU time of a bulk phase went (--cpu-report): per thread name, from
// /proc/self/task/*/schedstat (ns on a CPU), and per CPU from /proc/stat (busy and
// softirq jiffies: the veth's receive path runs in the sender CPU's softirq).
struct CpuSnapshot {
  std::map<std::string, int64_t> thread_ns;  // by thread name (threads of one name summed)
  std::vector<std::array<uint64_t, 3>> cpu;  // per CPU: busy, softirq, total jiffies
  static CpuSnapshot take() {
    CpuSnapshot s;
    if (DIR* d = opendir("/proc/self/task")) {
      while (const dirent* e = readdir(d)) {
        if (e->d_name[0] == '.') continue;
        const std::string base = std::string("/proc/self/task/") + e->d_name;
        std::ifstream comm(base + "/comm"), sched(base + "/schedstat"), st(base + "/stat");
        std::string name, stat_line;
        int64_t ns = 0;
        if (!std::getline(comm, name) || !(sched >> ns)) continue;
        // The CPU it last ran on (field 39 of stat; our threads are pinned, so this
        // tells host A's from host B's), after the parenthesised name.
        if (std::getline(st, stat_line)) {
          std::istringstream in(stat_line.substr(stat_line.rfind(')') + 2));
          std::string field;
          for (int f = 3; f <= 39 && (in >> field); ++f) {
            if (f == 39) name += "@" + field;
          }
        }
        s.thread_ns[name] += ns;
      }
      closedir(d);
    }
    std::ifstream stat("/proc/stat");
    std::string line;
    while (std::getline(stat, line)) {
      if (line.rfind("cpu", 0) != 0 || line.size() < 4 || line[3] == ' ') continue;
      std::istringstream in(line.substr(line.find(' ')));
      uint64_t v[8] = {};
      for (auto& x : v) in >> x;  // user nice system idle iowait irq softirq steal
      const uint64_t total = v[0] + v[1] + v[2] + v[3] + v[4] + v[5] + v[6] + v[7];
      s.cpu.push_back({total - v[3] - v[4], v[6], total});
    }
    return s;
  }
};

std::string cpu_report(const CpuSnapshot& a, const CpuSnapshot& b, double megabytes) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(1);
  for (std::size_t c = 0; c < std::min(a.cpu.size(), b.cpu.size()); ++c) {
    const double total = static_cast<double>(b.cpu[c][2] - a.cpu[c][2]);
    if (total <= 0) continue;
    o << "    CPU " << c << ": busy " << 100.0 * static_cast<double>(b.cpu[c][0] - a.cpu[c][0]) / total << "% (softirq "
      << 100.0 * static_cast<double>(b.cpu[c][1] - a.cpu[c][1]) / total << "%, all processes)\n";
  }
  o << "    this process, ms of CPU per MB received:";
  for (const auto& [name, ns] : b.thread_ns) {
    const auto it = a.thread_ns.find(name);
    const int64_t d = ns - (it == a.thread_ns.end() ? 0 : it->second);
    if (d > 1000000) o << ' ' << name << '=' << std::setprecision(2) << static_cast<double>(d) / 1e6 / megabytes;
  }
  o << '\n';
  return o.str();
}

// ---------------------------------------------------------------- raw LCM references

// Echoes BENCH_PING as BENCH_PONG, and counts BENCH_BULK messages (in host B).
// Whole messages queued for the bulk receiver on either side (TiMS inbox slots, LCM
// subscription queue).
constexpr int kReceiverQueue = 16;

// Bytes 0-7 of every bulk message: CLOCK_MONOTONIC at the send call (both hosts share
// the clock), for the one-way latency.
int64_t stamp_of(const void* p) {
  int64_t t = 0;
  std::memcpy(&t, p, sizeof t);
  return t;
}

// What a bulk receiver saw; filled by its thread, read after the tail.
struct BulkSink {
  std::mutex mutex;
  uint64_t count = 0, bytes = 0;
  int64_t last_ns = 0;
  std::vector<int64_t> latency_ns;
  void reset() {
    std::lock_guard lock(mutex);
    count = bytes = 0;
    last_ns = 0;
    latency_ns.clear();
  }
  void add(std::size_t size, int64_t stamp) {
    const int64_t now = rt::monotonic_ns();
    std::lock_guard lock(mutex);
    ++count;
    bytes += size;
    last_ns = now;
    latency_ns.push_back(now - stamp);
  }
};

// Echoes BENCH_PING as BENCH_PONG, and counts BENCH_BULK messages (in host B);
// BENCH_BULKZ carries zstd frames, decompressed here as the TiMS receiver does.
struct LcmEcho {
  explicit LcmEcho(const std::string& url) : lcm(url), dctx(ZSTD_createDCtx()), plain(kMaxBulk) {
    if (!lcm.good()) throw std::runtime_error("LCM " + url);
    lcm.subscribe("BENCH_PING", &LcmEcho::on_ping, this);
    // As many whole messages wait for the handler as for the TiMS reader (its inbox's
    // slots): the same buffering behind the socket on both sides.
    lcm.subscribe("BENCH_BULK", &LcmEcho::on_bulk, this)->setQueueCapacity(kReceiverQueue);
    lcm.subscribe("BENCH_BULKZ", &LcmEcho::on_bulkz, this)->setQueueCapacity(kReceiverQueue);
  }
  ~LcmEcho() { ZSTD_freeDCtx(dctx); }
  void on_ping(const lcm::ReceiveBuffer* r, const std::string&) { lcm.publish("BENCH_PONG", r->data, r->data_size); }
  void on_bulk(const lcm::ReceiveBuffer* r, const std::string&) {
    if (r->data_size >= 8) sink.add(r->data_size, stamp_of(r->data));
  }
  void on_bulkz(const lcm::ReceiveBuffer* r, const std::string&) {
    const std::size_t n = ZSTD_decompressDCtx(dctx, plain.data(), plain.size(), r->data, r->data_size);
    if (ZSTD_isError(n) == 0 && n >= 8) sink.add(n, stamp_of(plain.data()));
  }
  void run() {
    pollfd p{lcm.getFileno(), POLLIN, 0};
    while (!stop.load()) {
      if (poll(&p, 1, 50) > 0) lcm.handle();
    }
  }
  static constexpr std::size_t kMaxBulk = 1100 * 1000;
  lcm::LCM lcm;
  ZSTD_DCtx* dctx;
  std::vector<uint8_t> plain;
  std::atomic<bool> stop{false};
  BulkSink sink;
};

struct LcmPinger {
  explicit LcmPinger(const std::string& url) : lcm(url) {
    if (!lcm.good()) throw std::runtime_error("LCM " + url);
    lcm.subscribe("BENCH_PONG", &LcmPinger::on_pong, this);
  }
  void on_pong(const lcm::ReceiveBuffer*, const std::string&) { got = true; }
  // One round trip in ns, or -1 after a second without an answer.
  int64_t ping(const std::vector<uint8_t>& payload) {
    got = false;
    const int64_t t0 = rt::monotonic_ns();
    lcm.publish("BENCH_PING", payload.data(), static_cast<unsigned>(payload.size()));
    pollfd p{lcm.getFileno(), POLLIN, 0};
    while (!got) {
      if (rt::monotonic_ns() - t0 > rt::kNsPerSec) return -1;
      if (poll(&p, 1, 100) > 0) lcm.handle();
    }
    return rt::monotonic_ns() - t0;
  }
  lcm::LCM lcm;
  bool got = false;
};

// ---------------------------------------------------------------- TiMS sides

std::string host_b_text(const std::string& url) {
  return "host: bench-b\nsystem: 0\nhost_id: 0\nheap_prefault_mib: 16\nlcm_url: \"" + url +
         "\"\n"
         "components:\n"
         "  - name: gen\n    class: Generator\n    instance: 0\n    autostart: false\n"
         "    command_task: {priority: 80}\n    data_task: {priority: 79, period_ms: 1000}\n";
}

// Large uplink slots of the bulk senders (host file key tims: large_slots).
constexpr uint32_t kLargeSlots = 8;

// A bare TiMS host: router, transport, one mailbox.
struct TimsHost {
  TimsHost(uint8_t system, const std::string& url, tims::Compression c, uint32_t inbox_slot)
      : router(system),
        inbox(tims::Address::make(system, rack::class_ids::kScan3d, 0, 3), kReceiverQueue, inbox_slot),
        reply(tims::Address::make(system, tims::classes::kTool, 1, 1), 8, 64 * 1024) {
    tims::LcmTransportConfig cfg;
    tims::NetworkConfig n;
    n.url = url;
    n.compression = c;
    cfg.networks = {n};
    cfg.role = system == tims::kToolSystem ? tims::NodeRole::kTool : tims::NodeRole::kExecutor;
    cfg.large_slots = kLargeSlots;
    cfg.warn = [](const std::string& s) { std::fprintf(stderr, "  [transport] %s\n", s.c_str()); };
    router.add(inbox);
    router.add(reply);
    transport = std::make_unique<tims::LcmTransport>(router, cfg);
    transport->start();
  }
  ~TimsHost() {
    transport->stop();
    router.remove(inbox.address());
    router.remove(reply.address());
  }
  tims::Router router;
  tims::Mailbox inbox;
  tims::Mailbox reply;
  std::unique_ptr<tims::LcmTransport> transport;
};

struct BulkResult {
  std::string mechanism;
  std::size_t size = 0;
  uint64_t sent = 0, received = 0;
  double seconds = 0;
  double mb_per_s = 0;
  double loss = 0;
  uint64_t wire_bytes = 0;
  std::vector<int64_t> latency_ns;  // one-way, send call to receipt, per message
};

std::vector<uint8_t> bulk_payload(std::size_t n) {
  // Like a depth image or a point cloud's range channel: 16-bit samples of a smooth
  // surface with a little sensor noise in the low bits. Compressible, not trivially.
  // Same bytes for every mechanism.
  std::vector<uint8_t> v(n);
  std::mt19937 rng(42);
  for (std::size_t i = 0; i + 1 < n; i += 2) {
    const auto x = static_cast<double>(i % 1280), y = static_cast<double>(i / 1280);
    const auto depth = static_cast<uint16_t>(2000.0 + 500.0 * std::sin(x / 200.0) * std::cos(y / 150.0) +
                                             static_cast<double>(rng() % 4));
    v[i] = static_cast<uint8_t>(depth & 0xFF);
    v[i + 1] = static_cast<uint8_t>(depth >> 8);
  }
  return v;
}

// The tail: until every message arrived, or nothing arrived for 500 ms after the last
// send (the rest is lost).
void wait_tail(BulkSink& sink, int count) {
  const int64_t sent_ns = rt::monotonic_ns();
  for (;;) {
    rt::sleep_for(5 * rt::kNsPerMs);
    std::lock_guard lock(sink.mutex);
    if (sink.count >= static_cast<uint64_t>(count)) return;
    if (rt::monotonic_ns() - std::max(sink.last_ns, sent_ns) > 500 * rt::kNsPerMs) return;
  }
}

BulkResult finish(const char* name, BulkSink& sink, std::size_t size, int count, int64_t t0, uint64_t wire) {
  BulkResult r;
  std::lock_guard lock(sink.mutex);
  r.mechanism = name;
  r.size = size;
  r.sent = static_cast<uint64_t>(count);
  r.received = sink.count;
  r.seconds = static_cast<double>(sink.last_ns - t0) / 1e9;
  r.mb_per_s = r.seconds > 0 ? static_cast<double>(sink.bytes) / r.seconds / 1e6 : 0;
  r.loss = 1.0 - static_cast<double>(r.received) / static_cast<double>(r.sent);
  r.wire_bytes = wire;
  r.latency_ns = sink.latency_ns;
  return r;
}

// Raw LCM: publish() back to back (it blocks while the socket's send buffer is full);
// `cctx`: compress each message first (zstd level 1, as the TiMS link does).
BulkResult bulk_lcm(LcmEcho& echo, lcm::LCM& tx, std::size_t size, int count, ZSTD_CCtx* cctx) {
  auto payload = bulk_payload(size);
  std::vector<uint8_t> frame(cctx != nullptr ? ZSTD_compressBound(size) : 0);
  echo.sink.reset();
  uint64_t wire = 0;
  const int64_t t0 = rt::monotonic_ns();
  for (int i = 0; i < count; ++i) {
    const int64_t now = rt::monotonic_ns();
    std::memcpy(payload.data(), &now, sizeof now);
    if (cctx != nullptr) {
      const std::size_t n = ZSTD_compressCCtx(cctx, frame.data(), frame.size(), payload.data(), payload.size(), 1);
      if (ZSTD_isError(n) != 0) throw std::runtime_error("zstd compression failed");
      tx.publish("BENCH_BULKZ", frame.data(), static_cast<unsigned>(n));
      wire += n;
    } else {
      tx.publish("BENCH_BULK", payload.data(), static_cast<unsigned>(payload.size()));
      wire += size;
    }
  }
  wait_tail(echo.sink, count);
  return finish(cctx != nullptr ? "raw LCM+zstd" : "raw LCM", echo.sink, size, count, t0, wire);
}

BulkResult bulk_tims(TimsHost& tx, TimsHost& rx, std::size_t size, int count, const char* name, int reader_cpu,
                     int queue) {
  const auto payload = bulk_payload(size);
  BulkSink sink;
  std::atomic<bool> stop{false};
  std::thread reader([&] {
    pthread_setname_np(pthread_self(), "B-tims-reader");
    if (reader_cpu >= 0) pin(reader_cpu);  // host B's, as the raw LCM handler
    // Zero-copy, as a component reads large messages (peek/peek_end); the raw LCM
    // handler does not copy either.
    while (!stop.load()) {
      const auto r = rx.inbox.peek(50 * rt::kNsPerMs);
      if (r.status != tims::RecvStatus::kOk) continue;
      if (r.body.size() >= 8) sink.add(r.body.size(), stamp_of(r.body.data()));
      rx.inbox.peek_end();
    }
  });
  const auto before = tx.transport->counters();
  const int64_t t0 = rt::monotonic_ns();
  for (int i = 0; i < count; ++i) {
    const tims::MessageHeader h = tims::make_header(rx.inbox.address(), tx.reply.address(), tims::msg::kData, 1,
                                                    static_cast<uint8_t>(i), size);
    const int64_t now = rt::monotonic_ns();
    const tims::ConstBuffer parts[2] = {{&now, sizeof now}, {payload.data() + sizeof now, payload.size() - sizeof now}};
    (void)tx.router.send(h, std::span<const tims::ConstBuffer>(parts, 2));
    // Back-pressure like a blocking publish(): never more queued than the large uplink
    // holds (when full, it drops its oldest). Refilled in batches: at `queue` messages
    // not yet sent, wait until a third of them are left (default 6 and 2: one wake-up
    // per four messages). A deeper queue adds its length to the one-way latency.
    if (tx.transport->counters().messages_out - before.messages_out + static_cast<uint64_t>(queue) <
        static_cast<uint64_t>(i + 1)) {
      (void)tx.transport->wait_uplink(static_cast<uint32_t>(queue / 3), rt::kNsPerSec);
    }
  }
  wait_tail(sink, count);
  stop = true;
  reader.join();
  const auto after = tx.transport->counters();
  {
    // Where missing messages went (TiMS reports every loss; raw LCM cannot say).
    std::lock_guard lock(sink.mutex);
    if (sink.count < static_cast<uint64_t>(count)) {
      const auto rc = rx.transport->counters();
      std::fprintf(stderr,
                   "  [%s %zu B] %llu of %d missing: sent by the transport %llu, receiver totals: lost %llu, "
                   "sequence gaps %llu, delivery failed %llu, inbox dropped %llu\n",
                   name, size, static_cast<unsigned long long>(static_cast<uint64_t>(count) - sink.count), count,
                   static_cast<unsigned long long>(after.messages_out - before.messages_out),
                   static_cast<unsigned long long>(rc.lost_messages), static_cast<unsigned long long>(rc.sequence_gaps),
                   static_cast<unsigned long long>(rc.delivery_failed),
                   static_cast<unsigned long long>(rx.inbox.counters().dropped));
    }
  }
  return finish(name, sink, size, count, t0, after.wire_bytes_out - before.wire_bytes_out);
}

void print(const char* name, const Percentiles& p) {
  std::printf("  %-12s n=%-6llu min %7.1f  p50 %7.1f  p90 %7.1f  p99 %7.1f  p99.9 %7.1f  max %8.1f us\n", name,
              static_cast<unsigned long long>(p.samples), rack::bench::us(p.min_ns), rack::bench::us(p.p50_ns),
              rack::bench::us(p.p90_ns), rack::bench::us(p.p99_ns), rack::bench::us(p.p999_ns),
              rack::bench::us(p.max_ns));
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fputs(kUsage, stderr);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--iterations") o.iterations = std::atoi(next().c_str());
    else if (a == "--rounds") o.rounds = std::atoi(next().c_str());
    else if (a == "--bulk-count") o.bulk_count = std::atoi(next().c_str());
    else if (a == "--port") o.port = std::atoi(next().c_str());
    else if (a == "--json") o.json = next();
    else if (a == "--no-rpc") o.rpc = false;
    else if (a == "--cpu-report") o.cpu_report = true;
    else if (a == "--bulk") o.bulk = next();
    else if (a == "--bulk-rounds") o.bulk_rounds = std::max(1, std::atoi(next().c_str()));
    else if (a == "--bulk-queue")
      o.bulk_queue = std::clamp(std::atoi(next().c_str()), 1, static_cast<int>(kLargeSlots) - 1);
    else if (a == "--cpus") {
      const std::string v = next();
      if (v == "any") {
        o.cpu_a = o.cpu_b = -1;
      } else if (std::sscanf(v.c_str(), "%d,%d", &o.cpu_a, &o.cpu_b) != 2) {
        std::fputs(kUsage, stderr);
        return 2;
      }
    } else if (a == "--quick") {
      o.iterations = 1000;
      o.rounds = 2;
      o.bulk_count = 100;
      o.bulk_rounds = 2;
    } else {
      std::fputs(kUsage, a == "-h" || a == "--help" ? stdout : stderr);
      return a == "-h" || a == "--help" ? 0 : 2;
    }
  }
  if (geteuid() != 0) {
    std::fprintf(stderr, "bench_lcm: needs root (network namespaces)\n");
    return 1;
  }
  try {
    Namespaces ns;
    const std::string url = "udpm://239.255.76.67:" + std::to_string(o.port) + "?ttl=1&recv_buf_size=4194304";
    std::printf("bench_lcm: hosts %s (CPU %d) and %s (CPU %d) on a veth pair, %s\n", ns.a.c_str(), o.cpu_a,
                ns.b.c_str(), o.cpu_b, url.c_str());

    // Host B: a rack::Executor with a Generator, the raw LCM echo, and a bare TiMS
    // host (system 1) for the bulk test.
    rack::ComponentRegistry registry;
    rack::components::register_builtin(registry);
    const auto caps = rt::probe_capabilities();
    std::unique_ptr<rack::Executor> exec;
    std::unique_ptr<LcmEcho> echo;
    std::unique_ptr<TimsHost> rx_plain;
    std::thread echo_thread;
    in_ns(ns.b, o.cpu_b, [&] {
      auto loaded = rack::load_host_text(host_b_text(url), "bench_lcm.yaml", registry, caps);
      if (!loaded.errors.empty()) throw std::runtime_error(loaded.errors.front().str());
      rack::ExecutorOptions eo;
      eo.log = [](const std::string&) {};
      exec = std::make_unique<rack::Executor>(std::move(loaded.host), eo);
      exec->start();
      echo = std::make_unique<LcmEcho>(url);
      rx_plain = std::make_unique<TimsHost>(1, url, tims::Compression::kNone, 1100 * 1000);
    });
    echo_thread = std::thread([&] {
      pthread_setname_np(pthread_self(), "B-lcm-handler");
      if (o.cpu_b >= 0) pin(o.cpu_b);
      echo->run();
    });

    // Host A: the client tool, the raw pinger and bulk publisher, TiMS bulk senders.
    std::unique_ptr<TimsHost> tool, tx_plain, tx_zstd;
    std::unique_ptr<LcmPinger> pinger;
    std::unique_ptr<lcm::LCM> bulk_tx;
    in_ns(ns.a, o.cpu_a, [&] {
      tool = std::make_unique<TimsHost>(tims::kToolSystem, url, tims::Compression::kNone, 64 * 1024);
      pinger = std::make_unique<LcmPinger>(url);
      bulk_tx = std::make_unique<lcm::LCM>(url);
      tx_plain = std::make_unique<TimsHost>(2, url, tims::Compression::kNone, 64 * 1024);
      tx_zstd = std::make_unique<TimsHost>(3, url, tims::Compression::kZstd, 64 * 1024);
    });
    pthread_setname_np(pthread_self(), "A-main");
    if (o.cpu_a >= 0) pin(o.cpu_a);      // the measuring (client) thread belongs to host A
    rt::sleep_for(1500 * rt::kNsPerMs);  // discovery warm-up on every side

    // ------------------------------------------------------------ RPC
    tims::Endpoint ep(tool->router, tool->reply, 10);
    const tims::Address gen = tims::Address::make(0, rack::class_ids::kGenerator, 0);
    std::vector<std::byte> buf(64 * 1024);
    const std::vector<uint8_t> ping(64, 0x5a);
    std::vector<int64_t> rack_rt, lcm_rt;
    uint64_t rack_fail = 0, lcm_fail = 0;
    const int per_block = std::max(1, o.iterations / o.rounds);
    for (int round = 0; round < (o.rpc ? o.rounds : 0); ++round) {
      for (int w = 0; w < 50; ++w) (void)ep.call(gen, tims::msg::kGetStatus, buf, rt::kNsPerSec);
      for (int i = 0; i < per_block; ++i) {
        const int64_t t0 = rt::monotonic_ns();
        const auto r = ep.call(gen, tims::msg::kGetStatus, buf, rt::kNsPerSec);
        const int64_t dt = rt::monotonic_ns() - t0;
        if (r.status == tims::CallStatus::kOk) rack_rt.push_back(dt);
        else ++rack_fail;
      }
      for (int w = 0; w < 50; ++w) (void)pinger->ping(ping);
      for (int i = 0; i < per_block; ++i) {
        const int64_t dt = pinger->ping(ping);
        if (dt >= 0) lcm_rt.push_back(dt);
        else ++lcm_fail;
      }
    }
    const Percentiles pr = rack::bench::percentiles_of(rack_rt);
    const Percentiles pl = rack::bench::percentiles_of(lcm_rt);
    if (o.rpc) {
      std::printf("RPC round trip between two namespaces (us), %d rounds alternating:\n", o.rounds);
      print("TiMS RPC", pr);
      print("raw LCM ping", pl);
      std::printf("  ratio TiMS/LCM: p50 %.2fx, p90 %.2fx, p99 %.2fx (target p50 <= 1.15x); failures %llu / %llu\n",
                  pr.p50_ns / pl.p50_ns, pr.p90_ns / pl.p90_ns, pr.p99_ns / pl.p99_ns,
                  static_cast<unsigned long long>(rack_fail), static_cast<unsigned long long>(lcm_fail));
    }

    // ------------------------------------------------------------ bulk
    // Per size, the mechanisms alternate in --bulk-rounds rounds (the order flips every
    // round), so that both see the same load; each round's TiMS/raw ratio is kept.
    const auto wanted = [&](const std::string& mech) {
      const std::string list = "," + o.bulk + ",";
      const bool zstd = mech.find("+zstd") != std::string::npos;
      const std::string token = std::string(mech.rfind("TiMS", 0) == 0 ? "tims" : "lcm") + (zstd ? "+zstd" : "");
      return list.find("," + token + ",") != std::string::npos || (zstd && list.find(",zstd,") != std::string::npos);
    };
    struct Pair {
      const char* tims;
      const char* lcm;
    };
    const Pair pairs[2] = {{"TiMS", "raw LCM"}, {"TiMS+zstd", "raw LCM+zstd"}};
    ZSTD_CCtx* ref_cctx = ZSTD_createCCtx();
    std::vector<std::vector<BulkResult>> runs;  // per (size, mechanism): one per round
    std::vector<BulkResult> bulk;               // aggregated over the rounds
    std::vector<std::string> ratio_lines;
    std::ostringstream ratios_json;
    for (const std::size_t size : {std::size_t{100 * 1000}, std::size_t{1000 * 1000}}) {
      const int count = size > 500000 ? std::max(10, o.bulk_count / 4) : o.bulk_count;
      std::map<std::string, std::vector<BulkResult>> by_mech;
      const auto run = [&](const std::string& mech) {
        if (!wanted(mech)) return;
        const auto c0 = CpuSnapshot::take();
        BulkResult r;
        if (mech == "raw LCM") r = bulk_lcm(*echo, *bulk_tx, size, count, nullptr);
        else if (mech == "raw LCM+zstd") r = bulk_lcm(*echo, *bulk_tx, size, count, ref_cctx);
        else if (mech == "TiMS") r = bulk_tims(*tx_plain, *rx_plain, size, count, "TiMS", o.cpu_b, o.bulk_queue);
        else r = bulk_tims(*tx_zstd, *rx_plain, size, count, "TiMS+zstd", o.cpu_b, o.bulk_queue);
        if (o.cpu_report) {
          std::printf("  %s %zu B: %.1f MB/s\n%s", r.mechanism.c_str(), r.size, r.mb_per_s,
                      cpu_report(c0, CpuSnapshot::take(), static_cast<double>(r.received * r.size) / 1e6).c_str());
        }
        by_mech[mech].push_back(std::move(r));
      };
      for (int round = 0; round < o.bulk_rounds; ++round) {
        for (const auto& pr2 : pairs) {
          if (round % 2 == 0) {
            run(pr2.lcm);
            run(pr2.tims);
          } else {
            run(pr2.tims);
            run(pr2.lcm);
          }
        }
      }
      for (const char* mech : {"raw LCM", "TiMS", "raw LCM+zstd", "TiMS+zstd"}) {
        const auto& rs = by_mech[mech];
        if (rs.empty()) continue;
        BulkResult agg;
        agg.mechanism = mech;
        agg.size = size;
        std::vector<double> rates;
        for (const auto& r : rs) {
          agg.sent += r.sent;
          agg.received += r.received;
          agg.wire_bytes += r.wire_bytes;
          agg.latency_ns.insert(agg.latency_ns.end(), r.latency_ns.begin(), r.latency_ns.end());
          rates.push_back(r.mb_per_s);
        }
        std::sort(rates.begin(), rates.end());
        agg.mb_per_s = rates[(rates.size() - 1) / 2];  // median round (lower median)
        agg.loss = 1.0 - static_cast<double>(agg.received) / static_cast<double>(agg.sent);
        bulk.push_back(agg);
        runs.push_back(rs);
      }
      for (const auto& pr2 : pairs) {
        const auto& t = by_mech[pr2.tims];
        const auto& l = by_mech[pr2.lcm];
        if (t.empty() || t.size() != l.size()) continue;
        std::vector<double> q;
        for (std::size_t i = 0; i < t.size(); ++i) q.push_back(l[i].mb_per_s > 0 ? t[i].mb_per_s / l[i].mb_per_s : 0);
        std::sort(q.begin(), q.end());
        const double med = q.size() % 2 != 0 ? q[q.size() / 2] : (q[q.size() / 2 - 1] + q[q.size() / 2]) / 2;
        char line[200];
        std::snprintf(line, sizeof line,
                      "  %-9s / %-12s %7zu B: ratio per round p50 %.2fx, min %.2fx, max %.2fx (%zu rounds)", pr2.tims,
                      pr2.lcm, size, med, q.front(), q.back(), q.size());
        ratio_lines.emplace_back(line);
        ratios_json << (ratios_json.tellp() > 0 ? ", " : "") << "{\"tims\": \"" << pr2.tims << "\", \"reference\": \""
                    << pr2.lcm << "\", \"size\": " << size << ", \"p50\": " << rack::bench::json_number(med)
                    << ", \"min\": " << rack::bench::json_number(q.front())
                    << ", \"max\": " << rack::bench::json_number(q.back()) << ", \"rounds\": " << q.size() << "}";
      }
    }
    ZSTD_freeCCtx(ref_cctx);
    std::printf("Bulk A -> B (sender as fast as it may), %d rounds alternating; MB/s of the median round:\n",
                o.bulk_rounds);
    for (std::size_t i = 0; i < bulk.size(); ++i) {
      auto& b = bulk[i];
      std::string rounds;
      for (const auto& r : runs[i]) {
        if (!rounds.empty()) rounds += ' ';
        rounds += std::to_string(static_cast<int>(r.mb_per_s));
      }
      std::printf("  %-12s %7zu B x %4llu: received %4llu (loss %5.1f%%), %7.1f MB/s (rounds: %s), wire %.1f MB\n",
                  b.mechanism.c_str(), b.size, static_cast<unsigned long long>(b.sent),
                  static_cast<unsigned long long>(b.received), 100 * b.loss, b.mb_per_s, rounds.c_str(),
                  static_cast<double>(b.wire_bytes) / 1e6);
    }
    std::printf("Throughput TiMS / raw LCM (target >= 0.90x, loss no higher):\n");
    for (const auto& l : ratio_lines) std::printf("%s\n", l.c_str());
    std::printf(
        "One-way latency per message, send call to receipt (ms; includes the queue in front of a\n"
        "saturated link, which differs: up to %d messages in the TiMS uplink, the socket buffers for LCM):\n",
        o.bulk_queue);
    for (auto& b : bulk) {
      std::vector<int64_t> v = b.latency_ns;
      const Percentiles p = rack::bench::percentiles_of(v);
      std::printf("  %-12s %7zu B: p50 %7.2f  p90 %7.2f  p99 %7.2f  max %7.2f\n", b.mechanism.c_str(), b.size,
                  p.p50_ns / 1e6, p.p90_ns / 1e6, p.p99_ns / 1e6, p.max_ns / 1e6);
    }

    if (!o.json.empty()) {
      std::ostringstream j;
      j << "{\"machine\": " << rack::bench::json_machine() << ", \"url\": \"" << rack::bench::json_escape(url)
        << "\", \"rpc\": {\"tims\": " << rack::bench::json_percentiles(pr)
        << ", \"lcm\": " << rack::bench::json_percentiles(pl) << ", \"tims_failures\": " << rack_fail
        << ", \"lcm_failures\": " << lcm_fail << "}, \"bulk_rounds\": " << o.bulk_rounds << ", \"bulk\": [";
      for (std::size_t i = 0; i < bulk.size(); ++i) {
        auto& b = bulk[i];
        std::vector<int64_t> v = b.latency_ns;
        j << (i ? ", " : "") << "{\"mechanism\": \"" << b.mechanism << "\", \"size\": " << b.size
          << ", \"sent\": " << b.sent << ", \"received\": " << b.received
          << ", \"mb_per_s\": " << rack::bench::json_number(b.mb_per_s)
          << ", \"loss\": " << rack::bench::json_number(b.loss) << ", \"wire_bytes\": " << b.wire_bytes
          << ", \"rounds_mb_per_s\": [";
        for (std::size_t k = 0; k < runs[i].size(); ++k)
          j << (k ? ", " : "") << rack::bench::json_number(runs[i][k].mb_per_s);
        j << "], \"latency\": " << rack::bench::json_percentiles(rack::bench::percentiles_of(v)) << "}";
      }
      j << "], \"bulk_ratios\": [" << ratios_json.str() << "]}\n";
      rack::bench::write_file(o.json, j.str());
    }

    echo->stop = true;
    echo_thread.join();
    tool.reset();
    tx_plain.reset();
    tx_zstd.reset();
    rx_plain.reset();
    exec->stop();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_lcm: %s\n", e.what());
    return 1;
  }
  return 0;
}
