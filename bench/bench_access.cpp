// bench_access: what access control and authenticated links cost, each beside the
// same path without them, in the same run (issue 11).
//
// Part 1 (policy check): Router::send of a 64 B and a 100 KB message to a local
// mailbox, with an AccessControl of 16 rules where the 16th matches (with per-source
// rate and bandwidth buckets, never empty), against the same router without access
// control. One SCHED_FIFO thread alternates blocks of both sides; each sample is one
// send (clock_gettime around it); the mailbox is drained untimed between samples.
//
// Part 2 (MAC): signing (LinkSigner::sign, keyed BLAKE2b) and verifying
// (LinkVerifier::verify, replay window included) one payload of 64 B and 100 KB,
// beside a memcpy of the same payload (what publishing copies anyway).
//
// Part 3 (end to end): a TiMS RPC (request and reply of 64 B, and of 100 KB) between
// two LcmTransports in this process on a private udpm port, keyed against unkeyed,
// alternating rounds.
//
// Part 4 (flood): the wake-up latency of a 1 kHz SCHED_FIFO task that sends one
// message per cycle to a protected mailbox, idle against while another (normal)
// thread floods the same mailbox as fast as it can from a rate-limited source (every
// flood message is checked, and almost all are refused). Alternating rounds.
//
// Prints a Markdown section (bench/RESULTS.md) and, with --json FILE, JSON.
#include <pthread.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <sys/stat.h>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "rack/components/class_ids.h"
#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/thread.h"
#include "rack/tims/access.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/link_auth.h"
#include "rack/tims/router.h"

namespace rack::bench {
namespace {

using tims::Address;

struct Options {
  int cpu = 1;
  int priority = 80;
  int samples = 20000;    // per side and size (parts 1 and 2)
  int rpcs = 2000;        // per side and size (part 3)
  int flood_seconds = 4;  // per side (part 4), in rounds of 1 s
  int port = 7893;
  std::string json;
};

constexpr std::size_t kSmall = 64;
constexpr std::size_t kLarge = 100 * 1024;
constexpr int kBlock = 200;

constexpr Address kDest = Address::make(0, class_ids::kChassis, 0, 0);
constexpr Address kSrc = Address::make(0, class_ids::kPilot, 0, 0);

tims::AccessConfig sixteen_rules() {
  tims::AccessConfig c;
  for (int i = 0; i < 15; ++i) {  // 15 rules for other components
    tims::AccessRuleConfig r;
    r.name = "other" + std::to_string(i);
    r.to.push_back({Address::make(0, 0x60, static_cast<uint8_t>(i), 0).raw(), 0xFFFFFF00u});
    r.rate = 100;
    c.rules.push_back(r);
  }
  tims::AccessRuleConfig r;
  r.name = "chassis";
  r.to.push_back({kDest.raw(), 0xFFFFFF00u});
  r.from.push_back({kSrc.raw(), 0xFFFFFF00u});
  r.any_type = false;
  r.types.set(21 + 128);
  r.max_priority = 50;
  r.rate = 1e9;  // never empty: the check's full path, always allowed
  r.burst = 1e6;
  r.bandwidth = 1e15;
  r.burst_bytes = 1e12;
  c.rules.push_back(r);
  return c;
}

struct Pair {
  std::string label;
  Percentiles with, without;
};

// Part 1.
Pair measure_check(const Options& o, std::size_t body) {
  Pair res;
  res.label = std::to_string(body) + " B";
  tims::AccessControl access(sixteen_rules());
  tims::Router plain(0), guarded(0);
  tims::Mailbox a(kDest, 4, static_cast<uint32_t>(body + 64)), b(kDest, 4, static_cast<uint32_t>(body + 64));
  plain.add(a);
  guarded.add(b);
  guarded.set_access(&access);
  std::vector<std::byte> payload(body), sink(body + 64);
  std::vector<int64_t> w, wo;
  w.reserve(static_cast<std::size_t>(o.samples));
  wo.reserve(static_cast<std::size_t>(o.samples));
  rt::Thread t;
  t.start(
      {"bench-access", o.priority, o.cpu, 256 * 1024},
      [&] {
        const auto one = [&](tims::Router& r, tims::Mailbox& m, std::vector<int64_t>* out) {
          const tims::MessageHeader h = tims::make_header(kDest, kSrc, 21, 10, 1, body);
          const tims::ConstBuffer part{payload.data(), payload.size()};
          const int64_t t0 = rt::monotonic_ns();
          const auto s = r.send(h, std::span<const tims::ConstBuffer>(&part, 1));
          const int64_t t1 = rt::monotonic_ns();
          if (!tims::delivered(s)) std::fprintf(stderr, "bench_access: send failed: %s\n", tims::describe(s));
          (void)m.receive(sink, tims::Mailbox::kNonBlocking);
          if (out != nullptr) out->push_back(t1 - t0);
        };
        for (int i = 0; i < 2000; ++i) {
          one(plain, a, nullptr);
          one(guarded, b, nullptr);
        }
        while (static_cast<int>(w.size()) < o.samples) {
          for (int k = 0; k < kBlock; ++k) one(guarded, b, &w);
          for (int k = 0; k < kBlock; ++k) one(plain, a, &wo);
        }
      },
      true);
  t.join();
  guarded.set_access(nullptr);
  res.with = percentiles_of(w);
  res.without = percentiles_of(wo);
  return res;
}

struct MacResult {
  std::string label;
  Percentiles sign, verify, copy;
};

// Part 2.
MacResult measure_mac(const Options& o, const std::string& key_path, std::size_t body) {
  MacResult res;
  res.label = std::to_string(body) + " B";
  tims::KeyRing ring(key_path);
  tims::LinkSigner signer(ring, 12345);
  tims::LinkVerifier verifier(ring, 5'000'000'000);
  std::vector<uint8_t> packet(body + tims::kAuthTrailerBytes, 0x5A), copy(body);
  std::vector<int64_t> s, v, c;
  for (int i = 0; i < o.samples; ++i) {
    if (i % kBlock == 0) {
      for (int k = 0; k < kBlock && i + k < o.samples; ++k) {
        const int64_t t0 = rt::monotonic_ns();
        std::memcpy(copy.data(), packet.data(), body);
        const int64_t t1 = rt::monotonic_ns();
        c.push_back(t1 - t0);
      }
    }
    const int64_t now = rt::host_time_ns();
    const int64_t t0 = rt::monotonic_ns();
    signer.sign("TIMS", packet.data(), body, packet.data() + body, now);
    const int64_t t1 = rt::monotonic_ns();
    const auto r = verifier.verify("TIMS", packet.data(), packet.size(), now, t1);
    const int64_t t2 = rt::monotonic_ns();
    if (r != tims::AuthResult::kOk) std::fprintf(stderr, "bench_access: verify: %s\n", tims::describe(r));
    s.push_back(t1 - t0);
    v.push_back(t2 - t1);
  }
  res.sign = percentiles_of(s);
  res.verify = percentiles_of(v);
  res.copy = percentiles_of(c);
  return res;
}

// Part 3: one side of the RPC pair.
struct Side {
  tims::Router router;
  tims::Mailbox box;
  std::unique_ptr<tims::LcmTransport> transport;
  Side(uint8_t system, const std::string& url, const std::string& key, std::size_t slot)
      : router(system), box(Address::make(system, class_ids::kProbe, 0, 0), 8, static_cast<uint32_t>(slot)) {
    router.add(box);
    tims::LcmTransportConfig c;
    tims::NetworkConfig n;
    n.url = url;
    n.key_file = key;
    c.networks.push_back(n);
    c.announce_period_ns = 0;
    c.warn = [](const std::string& s) { std::fprintf(stderr, "bench_access: %s\n", s.c_str()); };
    transport = std::make_unique<tims::LcmTransport>(router, c);
    transport->start();
  }
  ~Side() {
    transport->stop();
    router.remove(box.address());
  }
};

Percentiles rpc_round(const std::string& url, const std::string& key, std::size_t body, int count) {
  const std::size_t slot = body + 1024;
  Side client(1, url, key, slot), server(2, url, key, slot);
  std::atomic<bool> stop{false};
  std::thread echo([&] {
    std::vector<std::byte> buf(slot);
    tims::Endpoint ep(server.router, server.box, 10);
    while (!stop.load(std::memory_order_relaxed)) {
      const auto r = server.box.receive(buf, 100'000'000);
      if (r.status != tims::RecvStatus::kOk) continue;
      const tims::ConstBuffer part{buf.data() + sizeof(tims::MessageHeader), r.length - sizeof(tims::MessageHeader)};
      (void)ep.reply(r.header, tims::msg::kOk, std::span<const tims::ConstBuffer>(&part, 1));
    }
  });
  tims::Endpoint ep(client.router, client.box, 10);
  std::vector<std::byte> payload(body), reply(slot);
  const tims::ConstBuffer part{payload.data(), payload.size()};
  std::vector<int64_t> lat;
  uint64_t failed = 0;
  for (int i = 0; i < count + 50; ++i) {
    const int64_t t0 = rt::monotonic_ns();
    const auto r = ep.call(server.box.address(), 21, std::span<const tims::ConstBuffer>(&part, 1), reply,
                           1'000'000'000);
    const int64_t t1 = rt::monotonic_ns();
    if (r.status != tims::CallStatus::kOk) {
      ++failed;
      continue;
    }
    if (i >= 50) lat.push_back(t1 - t0);
  }
  stop = true;
  echo.join();
  if (failed > 0)
    std::fprintf(stderr, "bench_access: %llu RPC(s) without a reply (%zu B, %s)\n",
                 static_cast<unsigned long long>(failed), body, key.empty() ? "unkeyed" : "keyed");
  return percentiles_of(lat);
}

Pair measure_rpc(const Options& o, const std::string& key, std::size_t body) {
  Pair res;
  res.label = std::to_string(body) + " B";
  const std::string url = "udpm://239.255.76.67:" + std::to_string(o.port) + "?ttl=0&recv_buf_size=4194304";
  // Alternating rounds: both sides see the same background load.
  std::vector<Percentiles> rounds_w, rounds_wo;
  const int rounds = 4;
  for (int k = 0; k < rounds; ++k) {
    rounds_wo.push_back(rpc_round(url, "", body, o.rpcs / rounds));
    rounds_w.push_back(rpc_round(url, key, body, o.rpcs / rounds));
  }
  // Merge by re-running percentiles over the rounds' medians would lose the tails:
  // keep the round with the median p50 of each side instead (stated in the output).
  const auto mid = [](std::vector<Percentiles> v) {
    std::sort(v.begin(), v.end(), [](const Percentiles& a, const Percentiles& b) { return a.p50_ns < b.p50_ns; });
    return v[v.size() / 2];
  };
  res.with = mid(rounds_w);
  res.without = mid(rounds_wo);
  return res;
}

// Part 4.
struct FloodResult {
  Percentiles idle, flood;
  uint64_t flood_checked = 0, flood_denied = 0;
};

FloodResult measure_flood(const Options& o) {
  FloodResult res;
  tims::AccessConfig c;
  tims::AccessRuleConfig flood_rule;
  flood_rule.name = "flooder";
  flood_rule.to.push_back({kDest.raw(), 0xFFFFFF00u});
  flood_rule.from.push_back({Address::make(9, 0x90, 0, 0).raw(), 0xFFFFFF00u});
  flood_rule.rate = 100;
  flood_rule.burst = 10;
  c.rules.push_back(flood_rule);
  tims::AccessRuleConfig ok;
  ok.name = "task";
  ok.to.push_back({kDest.raw(), 0xFFFFFF00u});
  c.rules.push_back(ok);
  tims::AccessControl access(c);
  tims::Router router(0);
  tims::Mailbox box(kDest, 64, 256);
  router.add(box);
  router.set_access(&access);
  std::atomic<bool> flooding{false}, done{false};
  std::atomic<uint64_t> checked{0};
  std::thread flood([&] {
    const tims::MessageHeader h = tims::make_header(kDest, Address::make(9, 0x90, 0, 0), -6, 0, 0, 0);
    std::array<std::byte, sizeof h> raw{};
    std::memcpy(raw.data(), &h, sizeof h);
    while (!done.load(std::memory_order_relaxed)) {
      if (!flooding.load(std::memory_order_relaxed)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        continue;
      }
      for (int i = 0; i < 1000; ++i) (void)router.deliver_local(raw);  // as a receive thread would
      checked.fetch_add(1000, std::memory_order_relaxed);
    }
  });
  std::vector<int64_t> idle, busy;
  rt::Thread t;
  t.start(
      {"bench-flood", o.priority, o.cpu, 256 * 1024},
      [&] {
        std::vector<std::byte> sink(256);
        for (int round = 0; round < 2 * o.flood_seconds; ++round) {
          const bool f = round % 2 == 1;
          flooding.store(f);
          auto& out = f ? busy : idle;
          int64_t next = rt::monotonic_ns() + 1'000'000;
          for (int i = 0; i < 1000; ++i) {
            const timespec ts = rt::to_timespec(next);
            clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
            const int64_t woke = rt::monotonic_ns();
            if (i >= 20) out.push_back(woke - next);  // skip the switch-over
            const tims::MessageHeader h = tims::make_header(kDest, kSrc, 21, 10, 0, 0);
            (void)router.send(h, std::span<const tims::ConstBuffer>{});
            while (box.receive(sink, tims::Mailbox::kNonBlocking).status == tims::RecvStatus::kOk) {
            }
            next += 1'000'000;
          }
        }
        flooding.store(false);
      },
      true);
  t.join();
  done = true;
  flood.join();
  router.set_access(nullptr);
  router.remove(kDest);
  res.idle = percentiles_of(idle);
  res.flood = percentiles_of(busy);
  res.flood_checked = checked.load();
  res.flood_denied = access.counters()[0].denied();
  return res;
}

std::string row(const std::string& what, const Percentiles& p) {
  char b[256];
  std::snprintf(b, sizeof b, "| %s | %.3f | %.3f | %.3f | %.3f | %.3f |\n", what.c_str(), us(p.p50_ns), us(p.p90_ns),
                us(p.p99_ns), us(p.p999_ns), us(p.max_ns));
  return b;
}
std::string ratio(const Percentiles& a, const Percentiles& b) {
  char r[160];
  std::snprintf(r, sizeof r, "p50 %.2fx, p99 %.2fx", b.p50_ns > 0 ? a.p50_ns / b.p50_ns : 0.0,
                b.p99_ns > 0 ? a.p99_ns / b.p99_ns : 0.0);
  return r;
}

}  // namespace
}  // namespace rack::bench

int main(int argc, char** argv) {
  using namespace rack::bench;
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_access: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--cpu") o.cpu = std::atoi(next().c_str());
    else if (a == "--priority") o.priority = std::atoi(next().c_str());
    else if (a == "--samples") o.samples = std::atoi(next().c_str());
    else if (a == "--rpcs") o.rpcs = std::atoi(next().c_str());
    else if (a == "--flood-seconds") o.flood_seconds = std::atoi(next().c_str());
    else if (a == "--port") o.port = std::atoi(next().c_str());
    else if (a == "--json") o.json = next();
    else if (a == "--quick") {
      o.samples = 5000;
      o.rpcs = 400;
      o.flood_seconds = 2;
    } else {
      // -h: the usage on stdout, exit 0, as every other benchmark; anything else: exit 2.
      const bool help = a == "-h" || a == "--help";
      if (!help) std::fprintf(stderr, "bench_access: unknown option '%s'\n", a.c_str());
      std::fputs(
          "usage: bench_access [--cpu N] [--priority P] [--samples N] [--rpcs N] [--flood-seconds S]\n"
          "                    [--port PORT] [--quick] [--json FILE]\n",
          help ? stdout : stderr);
      return help ? 0 : 2;
    }
  }
  (void)rack::rt::apply_memory_policy(64u << 20);
  PmQosHold qos(0);
  const std::string dir = "/tmp/bench_access_" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  const std::string key = dir + "/bench.key";
  if (const std::string err = rack::tims::generate_key_file(key); !err.empty()) {
    std::fprintf(stderr, "bench_access: %s\n", err.c_str());
    return 1;
  }
  std::vector<Pair> checks, rpcs;
  std::vector<MacResult> macs;
  for (std::size_t size : {kSmall, kLarge}) checks.push_back(measure_check(o, size));
  for (std::size_t size : {kSmall, kLarge}) macs.push_back(measure_mac(o, key, size));
  for (std::size_t size : {kSmall, kLarge}) rpcs.push_back(measure_rpc(o, key, size));
  const FloodResult flood = measure_flood(o);
  std::filesystem::remove_all(dir);

  std::string md;
  md += "### Policy check: Router::send to a local mailbox, 16 rules (16th matches) vs none (us per send)\n\n";
  md += "| side | p50 | p90 | p99 | p99.9 | max |\n|---|---|---|---|---|---|\n";
  for (const auto& c : checks)
    md += row(c.label + " with access control", c.with) + row(c.label + " without", c.without);
  md += "\n";
  for (const auto& c : checks) md += "- " + c.label + ": " + ratio(c.with, c.without) + "\n";
  md += "\n### MAC per message: sign and verify (keyed BLAKE2b, replay window) vs memcpy of the payload (us)\n\n";
  md += "| side | p50 | p90 | p99 | p99.9 | max |\n|---|---|---|---|---|---|\n";
  for (const auto& m : macs)
    md += row(m.label + " sign", m.sign) + row(m.label + " verify", m.verify) + row(m.label + " memcpy", m.copy);
  md += "\n### TiMS RPC between two transports (one process, udpm ttl=0): keyed vs unkeyed (us per round trip)\n\n";
  md += "| side | p50 | p90 | p99 | p99.9 | max |\n|---|---|---|---|---|---|\n";
  for (const auto& r : rpcs) md += row(r.label + " keyed", r.with) + row(r.label + " unkeyed", r.without);
  md += "\n";
  for (const auto& r : rpcs) md += "- " + r.label + ": " + ratio(r.with, r.without) + " (median round of 4 per side)\n";
  md += "\n### 1 kHz SCHED_FIFO task wake-up latency: idle vs a rate-limited flood of the same mailbox (us)\n\n";
  md += "| side | p50 | p90 | p99 | p99.9 | max |\n|---|---|---|---|---|---|\n";
  md += row("idle", flood.idle) + row("flood", flood.flood);
  char line[256];
  std::snprintf(line, sizeof line, "\n- flood: %llu messages checked, %llu refused; %s\n",
                static_cast<unsigned long long>(flood.flood_checked),
                static_cast<unsigned long long>(flood.flood_denied), ratio(flood.flood, flood.idle).c_str());
  md += line;
  std::fputs(md.c_str(), stdout);

  if (!o.json.empty()) {
    std::string j = "{\"machine\":" + json_machine() + ",\"check\":[";
    for (std::size_t i = 0; i < checks.size(); ++i) {
      j += (i ? "," : "") + std::string("{\"label\":\"") + checks[i].label +
           "\",\"with\":" + json_percentiles(checks[i].with) + ",\"without\":" + json_percentiles(checks[i].without) +
           "}";
    }
    j += "],\"mac\":[";
    for (std::size_t i = 0; i < macs.size(); ++i) {
      j += (i ? "," : "") + std::string("{\"label\":\"") + macs[i].label +
           "\",\"sign\":" + json_percentiles(macs[i].sign) + ",\"verify\":" + json_percentiles(macs[i].verify) +
           ",\"memcpy\":" + json_percentiles(macs[i].copy) + "}";
    }
    j += "],\"rpc\":[";
    for (std::size_t i = 0; i < rpcs.size(); ++i) {
      j += (i ? "," : "") + std::string("{\"label\":\"") + rpcs[i].label +
           "\",\"keyed\":" + json_percentiles(rpcs[i].with) + ",\"unkeyed\":" + json_percentiles(rpcs[i].without) + "}";
    }
    j += "],\"flood\":{\"idle\":" + json_percentiles(flood.idle) + ",\"flood\":" + json_percentiles(flood.flood) +
         ",\"checked\":" + std::to_string(flood.flood_checked) + ",\"denied\":" + std::to_string(flood.flood_denied) +
         "}}";
    if (!write_file(o.json, j)) {
      std::fprintf(stderr, "bench_access: cannot write %s\n", o.json.c_str());
      return 1;
    }
  }
  return 0;
}
