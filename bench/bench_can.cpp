// bench_can: round trip of one CAN frame from an RT task through the drivers' I/O path
// (rack::devices::CanPort: send(), then receive() with a timeout, which does recvmsg
// with the SO_TIMESTAMPNS control message, a ppoll when nothing is queued, the
// software filter and counters) beside a raw socket loop on the same sockets
// (send() and a blocking recv() of 16 bytes), in the same run.
//
// Both sides talk to the same echo task: a SCHED_FIFO thread that receives each frame
// on the other end and sends it straight back with raw calls. The transport is what
// this kernel has: an AF_UNIX SOCK_SEQPACKET socketpair carrying struct can_frame
// (no AF_CAN here); with --vcan IFACE it is two CAN_RAW sockets on a vcan interface
// instead (where the kernel has SocketCAN).
//
//   bench_can [--iterations N] [--rounds R] [--cpu-mode same|cross|both] [--gap-us US]
//             [--priority P] [--vcan IFACE] [--json FILE]
//
// Mechanisms alternate in blocks (rounds) so drifts of a shared VM hit both alike. The
// client sleeps --gap-us between round trips so RT throttling does not kick in.
// Needs root (SCHED_FIFO, mlockall).
#include <linux/can/raw.h>
#include <net/if.h>
#include <pthread.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "rack/devices/can_port.h"
#include "rack/rt/clock.h"

namespace {

using rack::bench::Percentiles;
namespace rt = rack::rt;

struct Options {
  int iterations = 20000;
  int rounds = 2;
  std::string cpu_mode = "both";
  int gap_us = 200;
  int priority = 80;
  std::string vcan;
  std::string json;
};

void make_rt(int cpu, int priority) {
  sched_param sp{};
  sp.sched_priority = priority;
  if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) != 0) {
    throw std::runtime_error("SCHED_FIFO refused (run as root)");
  }
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(cpu), &set);
  pthread_setaffinity_np(pthread_self(), sizeof set, &set);
}

int open_vcan(const std::string& ifname) {
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) throw std::runtime_error(std::string("socket(PF_CAN): ") + std::strerror(errno));
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, ifname.c_str(), IFNAMSIZ - 1);
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) throw std::runtime_error(ifname + ": no such interface");
  sockaddr_can a{};
  a.can_family = AF_CAN;
  a.can_ifindex = ifr.ifr_ifindex;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) throw std::runtime_error("bind");
  return fd;
}

struct Result {
  std::string mechanism, placement;
  std::vector<int64_t> samples;
};

// One block of `n` round trips with one mechanism. The echo thread is already running.
void block(bool through_port, int client_fd, rack::devices::CanPort& port, int n, int gap_us,
           std::vector<int64_t>& out) {
  can_frame f{};
  f.can_id = 0x181;
  f.len = 8;
  for (int i = 0; i < n; ++i) {
    f.data[0] = static_cast<uint8_t>(i);
    const int64_t t0 = rt::monotonic_ns();
    if (through_port) {
      if (port.send(f).status != rack::devices::IoStatus::kOk) throw std::runtime_error("CanPort::send failed");
      can_frame back{};
      if (port.receive(back, rt::kNsPerSec).status != rack::devices::IoStatus::kOk || back.data[0] != f.data[0]) {
        throw std::runtime_error("CanPort::receive: no echo");
      }
    } else {
      if (::send(client_fd, &f, sizeof f, 0) != static_cast<ssize_t>(sizeof f)) throw std::runtime_error("send");
      can_frame back{};
      if (::recv(client_fd, &back, sizeof back, 0) != static_cast<ssize_t>(sizeof back) || back.data[0] != f.data[0]) {
        throw std::runtime_error("recv: no echo");
      }
    }
    out.push_back(rt::monotonic_ns() - t0);
    if (gap_us > 0) rt::sleep_for(gap_us * rt::kNsPerUs);
  }
}

std::pair<int, int> make_link(const Options& o) {
  if (o.vcan.empty()) {
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv) != 0) throw std::runtime_error("socketpair");
    return {sv[0], sv[1]};
  }
  return {open_vcan(o.vcan), open_vcan(o.vcan)};
}

// The echo side: raw blocking recv/send, answers each frame as a drive answers a PDO.
void echo_loop(int fd, int cpu, int priority) {
  make_rt(cpu, priority);
  can_frame f{};
  for (;;) {
    const ssize_t n = ::recv(fd, &f, sizeof f, 0);
    if (n != static_cast<ssize_t>(sizeof f) || f.can_id == 0x7FF) break;  // 0x7FF: stop
    f.can_id = 0x201;
    (void)::send(fd, &f, sizeof f, 0);
  }
}

std::vector<Result> run_placement(const Options& o, const std::string& placement) {
  // One link per mechanism (CanPort makes its socket non-blocking; the raw loop's recv
  // blocks), each with its own echo thread on the same CPU. On vcan both links share
  // the bus, so there the mechanisms run one after the other with the other's echo idle.
  const auto [raw_fd, raw_echo] = make_link(o);
  const auto [port_fd, port_echo] = make_link(o);
  const int client_cpu = 1;
  const int echo_cpu = placement == "same" ? 1 : 0;
  std::thread e1([&, fd = raw_echo] { echo_loop(fd, echo_cpu, o.priority); });
  std::thread e2([&, fd = port_echo] { echo_loop(fd, echo_cpu, o.priority); });
  Result raw{"raw-socket", placement, {}}, port_r{"CanPort", placement, {}};
  std::string error;
  std::thread client([&, raw_client = raw_fd, port_client = port_fd] {
    try {
      make_rt(client_cpu, o.priority);
      rack::devices::CanPort port;
      port.adopt(port_client);
      raw.samples.reserve(static_cast<std::size_t>(o.iterations * o.rounds));
      port_r.samples.reserve(static_cast<std::size_t>(o.iterations * o.rounds));
      std::vector<int64_t> warm;
      block(false, raw_client, port, 500, o.gap_us, warm);
      block(true, -1, port, 500, o.gap_us, warm);
      for (int r = 0; r < o.rounds; ++r) {
        block(false, raw_client, port, o.iterations, o.gap_us, raw.samples);
        block(true, -1, port, o.iterations, o.gap_us, port_r.samples);
      }
      can_frame stop{};
      stop.can_id = 0x7FF;
      (void)::send(raw_client, &stop, sizeof stop, 0);
      (void)port.send(stop);
    } catch (const std::exception& ex) {
      error = ex.what();
      ::shutdown(raw_client, SHUT_RDWR);
      ::shutdown(port_client, SHUT_RDWR);
    }
  });
  client.join();
  e1.join();
  e2.join();
  ::close(raw_fd);
  ::close(raw_echo);
  ::close(port_echo);  // port_fd belongs to the CanPort, closed with it
  if (!error.empty()) throw std::runtime_error(error);
  return {std::move(raw), std::move(port_r)};
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_can: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--iterations") o.iterations = std::atoi(next().c_str());
    else if (a == "--rounds") o.rounds = std::atoi(next().c_str());
    else if (a == "--cpu-mode") o.cpu_mode = next();
    else if (a == "--gap-us") o.gap_us = std::atoi(next().c_str());
    else if (a == "--priority") o.priority = std::atoi(next().c_str());
    else if (a == "--vcan") o.vcan = next();
    else if (a == "--json") o.json = next();
    else if (a == "--help" || a == "-h") {
      std::printf(
          "usage: bench_can [--iterations N] [--rounds R] [--cpu-mode same|cross|both] [--gap-us US]\n"
          "                 [--priority P] [--vcan IFACE] [--json FILE]\n");
      return 0;
    } else {
      std::fprintf(stderr, "bench_can: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (::mlockall(MCL_CURRENT | MCL_FUTURE) != 0) std::fprintf(stderr, "bench_can: mlockall failed (not root?)\n");
  rack::bench::PmQosHold pm(0);
  std::vector<std::string> placements;
  if (o.cpu_mode == "same" || o.cpu_mode == "both") placements.push_back("same");
  if (o.cpu_mode == "cross" || o.cpu_mode == "both") placements.push_back("cross");
  std::string json = "{\"machine\": " + rack::bench::json_machine() + ", \"transport\": \"" +
                     (o.vcan.empty() ? std::string("AF_UNIX SOCK_SEQPACKET") : "CAN_RAW " + o.vcan) +
                     "\", \"results\": [";
  std::printf("CAN frame round trip (%s), %d x %d round trips per mechanism, gap %d us, SCHED_FIFO %d\n",
              o.vcan.empty() ? "AF_UNIX SOCK_SEQPACKET socketpair" : ("CAN_RAW on " + o.vcan).c_str(), o.iterations,
              o.rounds, o.gap_us, o.priority);
  std::printf("| placement | mechanism | p50 us | p90 us | p99 us | p99.9 us | max us | p50 ratio | p99 ratio |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  bool first = true;
  try {
    for (const auto& pl : placements) {
      auto results = run_placement(o, pl);
      Percentiles ref = rack::bench::percentiles_of(results[0].samples);
      for (auto& r : results) {
        const Percentiles p = rack::bench::percentiles_of(r.samples);
        std::printf("| %s | %s | %.2f | %.2f | %.2f | %.2f | %.1f | %.2f | %.2f |\n", pl.c_str(), r.mechanism.c_str(),
                    p.p50_ns / 1e3, p.p90_ns / 1e3, p.p99_ns / 1e3, p.p999_ns / 1e3, p.max_ns / 1e3,
                    p.p50_ns / ref.p50_ns, p.p99_ns / ref.p99_ns);
        json += std::string(first ? "" : ", ") + "{\"placement\": \"" + pl + "\", \"mechanism\": \"" + r.mechanism +
                "\", \"percentiles\": " + rack::bench::json_percentiles(p) + "}";
        first = false;
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_can: %s\n", e.what());
    return 1;
  }
  json += "]}\n";
  if (!o.json.empty() && !rack::bench::write_file(o.json, json)) {
    std::fprintf(stderr, "bench_can: cannot write %s\n", o.json.c_str());
    return 1;
  }
  return 0;
}
