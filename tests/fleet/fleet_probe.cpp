// fleet_probe: the fleet test bed's measuring tool (tests/fleet/fleet.py). One process,
// one thread per network namespace it listens in; each thread enters its namespace
// first, so the TiMS/LCM transport it then makes (a tool's: it never announces
// itself) has its sockets there.
//
//   fleet_probe discover --listen NS=URL[,NS=URL...] --hosts N --components M
//                        [--timeout-s S]
//       Listens from now on and prints one JSON line per listener when its discovery
//       table holds N hosts and M components in all (the hosts that announce on that
//       network, or that routers forward there: what every rackd on that network knows),
//       with the milliseconds since the probe started; then one summary line.
//       Exit 0 when every listener got there within S seconds (default 60), else 1.
//
//   fleet_probe rpc --ns NS --url URL --tool-id ID --count C [--timeout-ms T] [--each]
//                   --group NAME=ADDR[,ADDR...] [--group ...]
//       Round trips of GET_STATUS from a tool endpoint in NS to each group's command
//       mailboxes (ADDR: the raw 32-bit address in hex), round robin, C per group,
//       alternating groups so both see the same machine load. Prints one JSON line per
//       group: count, replies, timeouts, p50/p90/p99/max in microseconds. --each: every
//       target of every group C times instead (reachability), no untimed first call.
//
// Not RT code (a test tool). Needs root (setns).
#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "rack/rt/clock.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/lcm_transport.h"

namespace {

namespace tims = rack::tims;
namespace rt = rack::rt;

constexpr const char* kUsage =
    "usage: fleet_probe discover --listen NS=URL[,NS=URL...] --hosts N --components M [--timeout-s S]\n"
    "       fleet_probe rpc --ns NS --url URL --tool-id ID --count C [--timeout-ms T] [--each]\n"
    "                       --group NAME=HEX[,HEX...] [--group ...]\n";

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr, "fleet_probe: %s\n%s", why.c_str(), kUsage);
  std::exit(2);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= s.size()) {
    const std::size_t at = s.find(sep, start);
    out.push_back(s.substr(start, at == std::string::npos ? std::string::npos : at - start));
    if (at == std::string::npos) break;
    start = at + 1;
  }
  return out;
}

void enter(const std::string& ns) {
  if (ns.empty() || ns == "-") return;  // the probe's own namespace
  const std::string path = "/run/netns/" + ns;
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
  const int rc = setns(fd, CLONE_NEWNET);
  close(fd);
  if (rc != 0) throw std::runtime_error("cannot enter " + path + ": " + std::strerror(errno));
}

// A tool on one network: router, reply mailbox, transport (it never announces).
struct Tool {
  Tool(const std::string& url, uint8_t id)
      : reply(tims::Address::make(tims::kToolSystem, tims::classes::kTool, id, 0), 8, 4096) {
    tims::LcmTransportConfig cfg;
    tims::NetworkConfig n;
    n.url = url;
    cfg.networks = {n};
    cfg.role = tims::NodeRole::kTool;
    cfg.warn = [](const std::string& s) { std::fprintf(stderr, "  [transport] %s\n", s.c_str()); };
    router.add(reply);
    transport = std::make_unique<tims::LcmTransport>(router, cfg);
    transport->start();
  }
  ~Tool() {
    transport->stop();
    router.remove(reply.address());
  }
  tims::Router router{tims::kToolSystem};
  tims::Mailbox reply;
  std::unique_ptr<tims::LcmTransport> transport;
};

int discover(int argc, char** argv) {
  std::vector<std::pair<std::string, std::string>> listen;
  std::size_t want_hosts = 0, want_components = 0;
  double timeout_s = 60;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--listen") {
      for (const auto& item : split(value(), ',')) {
        const auto eq = item.find('=');
        if (eq == std::string::npos) usage("--listen wants NS=URL, got '" + item + "'");
        listen.emplace_back(item.substr(0, eq), item.substr(eq + 1));
      }
    } else if (a == "--hosts") {
      want_hosts = std::strtoul(value().c_str(), nullptr, 10);
    } else if (a == "--components") {
      want_components = std::strtoul(value().c_str(), nullptr, 10);
    } else if (a == "--timeout-s") {
      timeout_s = std::strtod(value().c_str(), nullptr);
    } else {
      usage("unknown option " + a);
    }
  }
  if (listen.empty() || want_hosts == 0) usage("discover needs --listen and --hosts");
  const int64_t t0 = rt::monotonic_ns();
  const int64_t deadline = t0 + static_cast<int64_t>(timeout_s * 1e9);
  std::atomic<int> failed{0};
  std::vector<int64_t> done_ms(listen.size(), -1), done_ns(listen.size(), -1);
  std::vector<std::size_t> last_hosts(listen.size(), 0), last_components(listen.size(), 0);
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < listen.size(); ++k) {
    threads.emplace_back([&, k] {
      try {
        enter(listen[k].first);
        Tool tool(listen[k].second, static_cast<uint8_t>(200 + k % 50));
        while (rt::monotonic_ns() < deadline) {
          const auto hosts = tool.transport->hosts();
          std::size_t components = 0;
          for (const auto& h : hosts) components += h.components.size();
          last_hosts[k] = hosts.size();
          last_components[k] = components;
          if (hosts.size() >= want_hosts && components >= want_components) {
            done_ns[k] = rt::monotonic_ns();
            done_ms[k] = (done_ns[k] - t0) / rt::kNsPerMs;
            break;
          }
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
      } catch (const std::exception& e) {
        std::fprintf(stderr, "fleet_probe: %s: %s\n", listen[k].first.c_str(), e.what());
        failed.fetch_add(1);
      }
    });
  }
  for (auto& t : threads) t.join();
  int64_t worst = 0;
  bool all = failed.load() == 0;
  for (std::size_t k = 0; k < listen.size(); ++k) {
    std::printf("{\"listener\": \"%s\", \"ms\": %lld, \"monotonic_ns\": %lld, \"hosts\": %zu, \"components\": %zu}\n",
                listen[k].first.c_str(), static_cast<long long>(done_ms[k]), static_cast<long long>(done_ns[k]),
                last_hosts[k], last_components[k]);
    if (done_ms[k] < 0) all = false;
    worst = std::max(worst, done_ms[k]);
  }
  std::printf("{\"summary\": \"discover\", \"complete\": %s, \"worst_ms\": %lld}\n", all ? "true" : "false",
              static_cast<long long>(all ? worst : -1));
  return all ? 0 : 1;
}

struct Group {
  std::string name;
  std::vector<tims::Address> targets;
  std::vector<double> rtt_us;
  std::size_t replies = 0, timeouts = 0, not_ok = 0;
};

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return -1;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

int rpc(int argc, char** argv) {
  std::string ns, url;
  int tool_id = 250, count = 100;
  int64_t timeout_ns = 1'000'000'000;
  bool each = false;
  std::vector<Group> groups;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--ns") {
      ns = value();
    } else if (a == "--url") {
      url = value();
    } else if (a == "--tool-id") {
      tool_id = std::atoi(value().c_str());
    } else if (a == "--count") {
      count = std::atoi(value().c_str());
    } else if (a == "--timeout-ms") {
      timeout_ns = std::atoll(value().c_str()) * rt::kNsPerMs;
    } else if (a == "--each") {
      each = true;
    } else if (a == "--group") {
      const std::string g = value();
      const auto eq = g.find('=');
      if (eq == std::string::npos) usage("--group wants NAME=HEX[,HEX...]");
      Group grp;
      grp.name = g.substr(0, eq);
      for (const auto& h : split(g.substr(eq + 1), ',')) {
        grp.targets.emplace_back(static_cast<uint32_t>(std::strtoul(h.c_str(), nullptr, 16)));
      }
      groups.push_back(std::move(grp));
    } else {
      usage("unknown option " + a);
    }
  }
  if (url.empty() || groups.empty() || tool_id < 1 || tool_id > 254 || count < 1) usage("rpc needs --url and --group");
  int rc = 0;
  std::thread worker([&] {
    try {
      enter(ns);
      Tool tool(url, static_cast<uint8_t>(tool_id));
      tool.transport->wait_until_warm();
      tims::Endpoint ep(tool.router, tool.reply, 10);
      std::vector<std::byte> buffer(4096);
      const auto once = [&](Group& g, tims::Address t) {
        const int64_t start = rt::monotonic_ns();
        const tims::CallResult r = ep.call(t, tims::msg::kGetStatus, buffer, timeout_ns);
        const int64_t took = rt::monotonic_ns() - start;
        if (r.status == tims::CallStatus::kOk) {
          ++g.replies;
          if (r.reply.type < tims::msg::kOk && r.reply.type != tims::msg::kDisabled &&
              r.reply.type != tims::msg::kEnabled) {
            ++g.not_ok;
          }
          g.rtt_us.push_back(static_cast<double>(took) / 1e3);
        } else {
          ++g.timeouts;
        }
      };
      if (each) {  // reachability: every target once per round, nothing untimed first
        for (int n = 0; n < count; ++n) {
          for (auto& g : groups) {
            for (const auto t : g.targets) once(g, t);
          }
        }
        return;
      }
      // A first call to each target (not timed): the path's caches and ARP.
      for (auto& g : groups) {
        for (const auto t : g.targets) (void)ep.call(t, tims::msg::kGetStatus, buffer, timeout_ns);
      }
      for (int n = 0; n < count; ++n) {
        for (auto& g : groups) once(g, g.targets[static_cast<std::size_t>(n) % g.targets.size()]);
      }
    } catch (const std::exception& e) {
      std::fprintf(stderr, "fleet_probe: %s\n", e.what());
      rc = 1;
    }
  });
  worker.join();
  for (const auto& g : groups) {
    std::printf(
        "{\"group\": \"%s\", \"targets\": %zu, \"count\": %d, \"replies\": %zu, \"timeouts\": %zu, \"not_ok\": %zu, "
        "\"p50_us\": %.1f, \"p90_us\": %.1f, \"p99_us\": %.1f, \"max_us\": %.1f}\n",
        g.name.c_str(), g.targets.size(), count, g.replies, g.timeouts, g.not_ok, percentile(g.rtt_us, 0.5),
        percentile(g.rtt_us, 0.9), percentile(g.rtt_us, 0.99), percentile(g.rtt_us, 1.0));
    if (g.replies == 0) rc = 1;
  }
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) usage("which command?");
  const std::string cmd = argv[1];
  if (cmd == "discover") return discover(argc, argv);
  if (cmd == "rpc") return rpc(argc, argv);
  if (cmd == "-h" || cmd == "--help") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  usage("unknown command " + cmd);
}
