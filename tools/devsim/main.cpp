// rack-devsim: the simulated devices of RACK-RT's drivers, from the shell, so that a
// host file with real drivers runs on a desk (and users can try their own drivers):
//
//   rack-devsim gps --link /tmp/rack-gps0 [--rate 10] [--lat 52.38 --lon 9.72] [--speed 1 --course 90]
//   rack-devsim cia402 --socket /tmp/rack-can0.sock [--nodes 1,2]
//   rack-devsim cia402 --can vcan0 [--nodes 1,2]        (where the kernel has SocketCAN)
//   rack-devsim hokuyo --link /tmp/rack-urg0
//   rack-devsim sick --port 2111
//   rack-devsim joystick --fifo /tmp/rack-js0 [--forward 0.5] [--turn 0.2] [--deadman 0]
//
// Each runs until SIGINT/SIGTERM or --duration SECONDS. A plain (non-RT) program.
#include <fcntl.h>
#include <linux/can/raw.h>
#include <linux/joystick.h>
#include <net/if.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "rack/rt/clock.h"
#include "rack/sims/cia402_sim.h"
#include "rack/sims/hokuyo_scip_sim.h"
#include "rack/sims/nmea_gps_sim.h"
#include "rack/sims/sick_lms1xx_sim.h"
#include "rack/version.h"

namespace {

constexpr const char* kUsage = R"(usage: rack-devsim DEVICE [options]

Simulated devices for RACK-RT's drivers. Runs until SIGINT/SIGTERM or --duration.

  gps       an NMEA 0183 receiver (GGA, RMC, GSA, VTG) on a pseudo-terminal
              --link PATH       symlink to the pty (give it to GpsNmea's 'device')
              --rate HZ         epochs per second (default 10)
              --lat DEG --lon DEG --alt M   start position (default 52.3826 9.7177 55)
              --speed M/S --course DEG      constant motion (default 1.0, 90 = east)
              --fault none|checksum|garbage|silent   start with a fault
  cia402    CANopen CiA 402 drives (profile velocity/position, NMT, SDO, PDO, SYNC,
            heartbeat) on a CAN-frame socket
              --socket PATH     listen on AF_UNIX SOCK_SEQPACKET (ChassisCan 'can: unix:PATH')
              --can IFACE       or a SocketCAN interface (vcan0, can0)
              --nodes LIST      node ids (default 1,2)
  hokuyo    a Hokuyo URG-04LX speaking SCIP 2.0 on a pseudo-terminal, in a rectangular room
              --link PATH       symlink to the pty (give it to LadarHokuyo's 'device')
              --rpm N           scan rate (default 600 = 10 Hz)
              --front M --side M    distances to the walls (default 2.0 and 1.5)
              --fault none|checksum|garbage|silent
  sick      a SICK LMS1xx speaking CoLa-A on 127.0.0.1 (541 points, -45..225 deg, 50 Hz)
              --port N          TCP port (default 2111; LadarSick 'host: 127.0.0.1', 'port')
              --fault none|garbage|truncated|silent
  joystick  a stick writing struct js_event into a FIFO (Joystick 'device')
              --fifo PATH       created if missing
              --forward F --turn T   deflection in [-1, 1] (default 0.5 forward, 0 turn)
              --deadman N       hold button N (default: none)
              --period-ms MS    repeat the state this often (default 100)

Common: --duration SECONDS, --help. rack-devsim --version prints the version.
)";

std::map<std::string, std::string> parse_options(int argc, char** argv, int first) {
  std::map<std::string, std::string> o;
  for (int i = first; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (a.rfind("--", 0) != 0 || i + 1 >= argc) {
      std::fprintf(stderr, "rack-devsim: unexpected argument '%s'\n%s", a.c_str(), kUsage);
      std::exit(2);
    }
    o[a.substr(2)] = argv[++i];
  }
  return o;
}

double number(const std::map<std::string, std::string>& o, const char* key, double def) {
  const auto it = o.find(key);
  if (it == o.end()) return def;
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  if (end == it->second.c_str() || *end != '\0' || !std::isfinite(v)) {
    std::fprintf(stderr, "rack-devsim: --%s: '%s' is not a number\n", key, it->second.c_str());
    std::exit(2);
  }
  return v;
}

// Waits for SIGINT/SIGTERM or the duration; `tick` runs every period_ms meanwhile.
template <typename F>
void run_until_stopped(double duration_s, int64_t period_ms, F&& tick) {
  sigset_t s;
  sigemptyset(&s);
  sigaddset(&s, SIGINT);
  sigaddset(&s, SIGTERM);
  const int64_t end = duration_s > 0 ? rack::rt::monotonic_ns() + static_cast<int64_t>(duration_s * 1e9) : INT64_MAX;
  while (rack::rt::monotonic_ns() < end) {
    const timespec ts = rack::rt::to_timespec(period_ms * rack::rt::kNsPerMs);
    if (sigtimedwait(&s, nullptr, &ts) > 0) break;
    tick();
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::string(argv[1]) == "--version") {
    rack::print_version("rack-devsim");
    return 0;
  }
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  // Block the stop signals in every thread (the simulators' threads inherit this).
  sigset_t s;
  sigemptyset(&s);
  sigaddset(&s, SIGINT);
  sigaddset(&s, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &s, nullptr);
  const std::string device = argv[1];
  const auto o = parse_options(argc, argv, 2);
  // The options each device takes (kUsage): another one is a usage error, never
  // ignored (a typo such as --rat 10 ran at the default rate, saying nothing).
  static const std::map<std::string, std::vector<std::string>> kDeviceOptions = {
      {"gps", {"link", "rate", "lat", "lon", "alt", "speed", "course", "fault", "duration"}},
      {"cia402", {"socket", "can", "nodes", "duration"}},
      {"hokuyo", {"link", "rpm", "front", "side", "fault", "duration"}},
      {"sick", {"port", "fault", "duration"}},
      {"joystick", {"fifo", "forward", "turn", "deadman", "period-ms", "duration"}}};
  if (const auto known = kDeviceOptions.find(device); known != kDeviceOptions.end()) {
    for (const auto& option : o) {
      if (std::find(known->second.begin(), known->second.end(), option.first) == known->second.end()) {
        std::fprintf(stderr, "rack-devsim %s: unknown option '--%s' (rack-devsim --help lists each device's)\n",
                     device.c_str(), option.first.c_str());
        return 2;
      }
    }
  }
  const double duration = number(o, "duration", 0.0);
  if (duration < 0) {
    std::fprintf(stderr, "rack-devsim: --duration needs seconds >= 0 (0: until SIGINT/SIGTERM)\n");
    return 2;
  }
  try {
    if (device == "gps") {
      rack::sims::NmeaGpsSim::Config c;
      if (!o.count("link")) throw std::runtime_error("gps needs --link PATH");
      c.link = o.at("link");
      const double rate = number(o, "rate", 10.0);
      if (rate <= 0 || rate > 100) throw std::runtime_error("--rate must be in (0, 100]");
      c.period_ns = static_cast<int64_t>(1e9 / rate);
      c.latitude_deg = number(o, "lat", c.latitude_deg);
      c.longitude_deg = number(o, "lon", c.longitude_deg);
      c.altitude_m = number(o, "alt", c.altitude_m);
      c.speed_mps = number(o, "speed", c.speed_mps);
      c.course_deg = number(o, "course", c.course_deg);
      rack::sims::NmeaGpsSim sim(c);
      sim.start();
      const std::string fault = o.count("fault") ? o.at("fault") : "none";
      using F = rack::sims::NmeaGpsSim::Fault;
      if (fault == "checksum") sim.set_fault(F::kBadChecksum);
      else if (fault == "garbage") sim.set_fault(F::kGarbage);
      else if (fault == "silent") sim.set_fault(F::kSilent);
      else if (fault != "none") throw std::runtime_error("--fault: none, checksum, garbage or silent");
      std::printf("rack-devsim gps: NMEA at %.1f Hz on %s\n", rate, sim.device().c_str());
      std::fflush(stdout);
      run_until_stopped(duration, 100, [] {});
      sim.stop();
      return 0;
    }
    if (device == "cia402") {
      rack::sims::Cia402DriveSim::Config c;
      if (o.count("nodes")) {
        c.nodes.clear();
        std::string list = o.at("nodes");
        for (std::size_t at = 0; at <= list.size();) {
          const std::size_t comma = std::min(list.find(',', at), list.size());
          const int n = std::atoi(list.substr(at, comma - at).c_str());
          if (n < 1 || n > 127) throw std::runtime_error("--nodes: ids 1..127, comma-separated");
          c.nodes.push_back(static_cast<uint8_t>(n));
          at = comma + 1;
        }
      }
      rack::sims::Cia402DriveSim sim(c);
      std::string where;
      if (o.count("socket")) {
        sim.listen_unix(o.at("socket"));
        where = "unix:" + o.at("socket");
      } else if (o.count("can")) {
        const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
        if (fd < 0) throw std::runtime_error(std::string("socket(PF_CAN): ") + std::strerror(errno));
        ifreq ifr{};
        std::strncpy(ifr.ifr_name, o.at("can").c_str(), IFNAMSIZ - 1);
        sockaddr_can addr{};
        addr.can_family = AF_CAN;
        if (::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) throw std::runtime_error(o.at("can") + ": no such interface");
        addr.can_ifindex = ifr.ifr_ifindex;
        if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
          throw std::runtime_error(o.at("can") + ": bind: " + std::strerror(errno));
        }
        sim.attach(fd);
        where = o.at("can");
      } else {
        throw std::runtime_error("cia402 needs --socket PATH or --can IFACE");
      }
      sim.start();
      std::printf("rack-devsim cia402: %zu drive(s) on %s\n", c.nodes.size(), where.c_str());
      std::fflush(stdout);
      run_until_stopped(duration, 100, [] {});
      sim.stop();
      return 0;
    }
    if (device == "hokuyo") {
      rack::sims::HokuyoScipSim::Config c;
      if (!o.count("link")) throw std::runtime_error("hokuyo needs --link PATH");
      c.link = o.at("link");
      c.scan_rpm = static_cast<uint32_t>(number(o, "rpm", 600));
      if (c.scan_rpm < 60 || c.scan_rpm > 6000) throw std::runtime_error("--rpm must be in [60, 6000]");
      c.room_front = number(o, "front", c.room_front);
      c.room_side = number(o, "side", c.room_side);
      rack::sims::HokuyoScipSim sim(c);
      sim.start();
      const std::string fault = o.count("fault") ? o.at("fault") : "none";
      using F = rack::sims::HokuyoScipSim::Fault;
      if (fault == "checksum") sim.set_fault(F::kBadChecksum);
      else if (fault == "garbage") sim.set_fault(F::kGarbage);
      else if (fault == "silent") sim.set_fault(F::kSilent);
      else if (fault != "none") throw std::runtime_error("--fault: none, checksum, garbage or silent");
      std::printf("rack-devsim hokuyo: SCIP 2.0 at %u rpm on %s\n", c.scan_rpm, sim.device().c_str());
      std::fflush(stdout);
      run_until_stopped(duration, 100, [] {});
      sim.stop();
      return 0;
    }
    if (device == "sick") {
      rack::sims::SickLms1xxSim::Config c;
      const double port = number(o, "port", 2111);
      if (port < 1 || port > 65535) throw std::runtime_error("--port must be in 1..65535");
      c.port = static_cast<uint16_t>(port);
      rack::sims::SickLms1xxSim sim(c);
      sim.start();
      const std::string fault = o.count("fault") ? o.at("fault") : "none";
      using F = rack::sims::SickLms1xxSim::Fault;
      if (fault == "garbage") sim.set_fault(F::kGarbage);
      else if (fault == "truncated") sim.set_fault(F::kTruncated);
      else if (fault == "silent") sim.set_fault(F::kSilent);
      else if (fault != "none") throw std::runtime_error("--fault: none, garbage, truncated or silent");
      std::printf("rack-devsim sick: CoLa-A on 127.0.0.1:%u\n", sim.port());
      std::fflush(stdout);
      run_until_stopped(duration, 100, [] {});
      sim.stop();
      return 0;
    }
    if (device == "joystick") {
      if (!o.count("fifo")) throw std::runtime_error("joystick needs --fifo PATH");
      const std::string path = o.at("fifo");
      if (::mkfifo(path.c_str(), 0600) != 0 && errno != EEXIST) {
        throw std::runtime_error(path + ": mkfifo: " + std::strerror(errno));
      }
      // O_RDWR: never blocks waiting for a reader, never SIGPIPE when it goes.
      const int fd = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
      if (fd < 0) throw std::runtime_error(path + ": " + std::strerror(errno));
      const double fwd = std::clamp(number(o, "forward", 0.5), -1.0, 1.0);
      const double turn = std::clamp(number(o, "turn", 0.0), -1.0, 1.0);
      const int deadman = static_cast<int>(number(o, "deadman", -1));
      const double period_ms = number(o, "period-ms", 100);
      // 0 or less repeated the state without pause (a core spinning on the FIFO).
      if (period_ms < 1 || period_ms > 60000) throw std::runtime_error("--period-ms must be in 1..60000");
      const auto period = static_cast<int64_t>(period_ms);
      auto write_state = [&] {
        auto ev = [&](uint8_t type, uint8_t n, double v) {
          js_event e{};
          e.time = static_cast<uint32_t>(rack::rt::monotonic_ns() / rack::rt::kNsPerMs);
          e.type = type;
          e.number = n;
          e.value = static_cast<int16_t>(std::lround(v));
          (void)!::write(fd, &e, sizeof e);
        };
        // Linux reports forward and left as negative values.
        ev(JS_EVENT_AXIS, 0, -turn * 32767);
        ev(JS_EVENT_AXIS, 1, -fwd * 32767);
        if (deadman >= 0) ev(JS_EVENT_BUTTON, static_cast<uint8_t>(deadman), 1);
      };
      std::printf("rack-devsim joystick: forward %.2f turn %.2f on %s\n", fwd, turn, path.c_str());
      std::fflush(stdout);
      run_until_stopped(duration, period, write_state);
      ::close(fd);
      return 0;
    }
    std::fprintf(stderr, "rack-devsim: unknown device '%s'\n%s", device.c_str(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rack-devsim %s: %s\n", device.c_str(), e.what());
    return 1;
  }
}
