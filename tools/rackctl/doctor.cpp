// rackctl doctor's checks (doctor.h). Each reads one or two files below the root and
// says what it found there; the fixes are the usual Debian ones (README: "Preparing a
// host for real time").
#include "doctor.h"

#include <arpa/inet.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

namespace rack::tools {
namespace {

namespace fs = std::filesystem;

std::optional<std::string> read_text(const fs::path& p) {
  std::ifstream in(p);
  if (!in) return std::nullopt;
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string first_line(const std::string& text) {
  const auto nl = text.find('\n');
  std::string l = nl == std::string::npos ? text : text.substr(0, nl);
  while (!l.empty() && (l.back() == '\r' || l.back() == ' ' || l.back() == '\t')) l.pop_back();
  return l;
}

fs::path under(const fs::path& root, const char* abs) { return root / fs::path(abs).relative_path(); }

// The soft limit of a /proc/PID/limits row ("Max realtime priority  0  0"): a number,
// or -1 for "unlimited"; nullopt when the row is missing or unreadable.
std::optional<long long> soft_limit(const std::string& limits, const std::string& row) {
  std::istringstream in(limits);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(row, 0) != 0) continue;
    std::istringstream fields(line.substr(row.size()));
    std::string soft;
    fields >> soft;
    if (soft == "unlimited") return -1;
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(soft.c_str(), &end, 10);
    if (soft.empty() || *end != '\0' || errno != 0) return std::nullopt;
    return v;
  }
  return std::nullopt;
}

// The effective capability set of /proc/self/status (CapEff, hex).
std::optional<uint64_t> effective_caps(const std::string& status) {
  std::istringstream in(status);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("CapEff:", 0) != 0) continue;
    const std::string hex = first_line(line.substr(7));
    char* end = nullptr;
    errno = 0;
    const unsigned long long v = std::strtoull(hex.c_str(), &end, 16);
    if (end == hex.c_str() || errno != 0) return std::nullopt;
    return v;
  }
  return std::nullopt;
}

constexpr int kCapIpcLock = 14;  // linux/capability.h
constexpr int kCapSysNice = 23;

bool has_cap(const std::optional<uint64_t>& caps, int bit) { return caps && ((*caps >> bit) & 1u) != 0; }

constexpr const char* kLimitsFix =
    "as root: printf '@realtime - rtprio 99\\n@realtime - memlock unlimited\\n' > "
    "/etc/security/limits.d/99-realtime.conf; groupadd -f realtime; usermod -aG realtime $USER; "
    "log in again (or run rackd with CAP_SYS_NICE and CAP_IPC_LOCK)";

DoctorCheck check_rt_priority(const fs::path& root, const std::optional<std::string>& limits,
                              const std::optional<uint64_t>& caps) {
  DoctorCheck c{"rt-priority", Verdict::kOk, "", ""};
  const auto where = under(root, "/proc/self/limits").string();
  if (has_cap(caps, kCapSysNice)) {
    c.found = "CAP_SYS_NICE held: any SCHED_FIFO priority is allowed";
    return c;
  }
  const auto v = limits ? soft_limit(*limits, "Max realtime priority") : std::nullopt;
  if (!v) {
    c.verdict = Verdict::kWarn;
    c.found = "cannot read 'Max realtime priority' in " + where;
    c.fix = std::string("check with: ulimit -r; ") + kLimitsFix;
    return c;
  }
  if (*v < 0 || *v >= 99) {
    c.found = "ulimit -r " + (*v < 0 ? std::string("unlimited") : std::to_string(*v));
    return c;
  }
  c.found = "ulimit -r " + std::to_string(*v) + " (" + where + ")";
  c.verdict = *v == 0 ? Verdict::kFail : Verdict::kWarn;
  c.found += *v == 0 ? ": no SCHED_FIFO at all, every task runs SCHED_OTHER"
                     : ": tasks with a priority above " + std::to_string(*v) + " are refused";
  c.fix = kLimitsFix;
  return c;
}

DoctorCheck check_memlock(const fs::path& root, const std::optional<std::string>& limits,
                          const std::optional<uint64_t>& caps) {
  DoctorCheck c{"memlock", Verdict::kOk, "", ""};
  if (has_cap(caps, kCapIpcLock)) {
    c.found = "CAP_IPC_LOCK held: mlockall is allowed";
    return c;
  }
  const auto v = limits ? soft_limit(*limits, "Max locked memory") : std::nullopt;
  if (!v) {
    c.verdict = Verdict::kWarn;
    c.found = "cannot read 'Max locked memory' in " + under(root, "/proc/self/limits").string();
    c.fix = std::string("check with: ulimit -l; ") + kLimitsFix;
    return c;
  }
  if (*v < 0) {
    c.found = "ulimit -l unlimited";
    return c;
  }
  c.verdict = Verdict::kFail;
  c.found = "ulimit -l " + std::to_string(*v / 1024) +
            " KiB: mlockall fails, rackd runs with memory not locked (page faults in RT tasks)";
  c.fix = kLimitsFix;
  return c;
}

// /proc/net/route: the most specific UP route that covers `group`, and its interface's
// flags (/sys/class/net/IFACE/flags: IFF_UP 0x1, IFF_MULTICAST 0x1000).
DoctorCheck check_multicast_route(const fs::path& root, const std::string& group) {
  DoctorCheck c{"multicast-route", Verdict::kOk, "", ""};
  const std::string fix_route =
      "one host: sudo ip link set lo multicast on && sudo ip route add 224.0.0.0/4 dev lo; "
      "on a network: sudo ip route add 224.0.0.0/4 dev IFACE (persist it in /etc/network/interfaces)";
  in_addr group_addr{};
  if (inet_pton(AF_INET, group.c_str(), &group_addr) != 1) {
    c.verdict = Verdict::kWarn;
    c.found = "'" + group + "' is not an IPv4 multicast group";
    c.fix = "give --lcm udpm://GROUP:PORT";
    return c;
  }
  const auto where = under(root, "/proc/net/route");
  const auto table = read_text(where);
  if (!table) {
    c.verdict = Verdict::kWarn;
    c.found = "cannot read " + where.string();
    c.fix = "check with: ip route get " + group;
    return c;
  }
  std::istringstream in(*table);
  std::string line;
  std::getline(in, line);  // the header
  std::string best_iface;
  int best_bits = -1;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string iface, dest, gateway, flags, refcnt, use, metric, mask;
    if (!(f >> iface >> dest >> gateway >> flags >> refcnt >> use >> metric >> mask)) continue;
    // The kernel prints each address as the u32 in memory (network byte order) with
    // %08X: reading it back the same way gives the same bytes as inet_pton.
    const auto d = static_cast<uint32_t>(std::strtoul(dest.c_str(), nullptr, 16));
    const auto m = static_cast<uint32_t>(std::strtoul(mask.c_str(), nullptr, 16));
    const auto fl = std::strtoul(flags.c_str(), nullptr, 16);
    if ((fl & 1u) == 0 || (group_addr.s_addr & m) != d) continue;
    const int bits = std::popcount(m);
    if (bits > best_bits) {
      best_bits = bits;
      best_iface = iface;
    }
  }
  if (best_bits < 0) {
    c.verdict = Verdict::kFail;
    c.found = "no route to " + group + " in " + where.string() +
              ": LCM cannot send (rackd and rackctl fail to join the network)";
    c.fix = fix_route;
    return c;
  }
  const auto flags_text = read_text(under(root, "/sys/class/net") / best_iface / "flags");
  const unsigned long iff = flags_text ? std::strtoul(first_line(*flags_text).c_str(), nullptr, 16) : 0;
  const std::string route = group + " goes to " + best_iface + (best_bits == 0 ? " (default route)" : "");
  if (!flags_text) {
    c.verdict = Verdict::kWarn;
    c.found = route + "; cannot read its flags";
    c.fix = "check with: ip link show " + best_iface;
  } else if ((iff & 0x1000u) == 0 || (iff & 0x1u) == 0) {
    c.verdict = Verdict::kFail;
    c.found = route + ", which is " + ((iff & 0x1u) == 0 ? "down" : "not multicast-capable");
    c.fix = "sudo ip link set " + best_iface + " up multicast on";
  } else {
    c.found = route + " (up, multicast)";
  }
  return c;
}

// LCM's own advice: a 2 MiB receive buffer at least (lcm-proj.github.io, multicast setup).
constexpr long long kRmemWanted = 2 * 1024 * 1024;

DoctorCheck check_rmem_max(const fs::path& root) {
  DoctorCheck c{"rmem-max", Verdict::kOk, "", ""};
  const auto where = under(root, "/proc/sys/net/core/rmem_max");
  const std::string fix = "sudo sysctl -w net.core.rmem_max=" + std::to_string(kRmemWanted) +
                          " and echo net.core.rmem_max=" + std::to_string(kRmemWanted) +
                          " | sudo tee /etc/sysctl.d/60-rack.conf";
  const auto text = read_text(where);
  char* end = nullptr;
  const long long v = text ? std::strtoll(text->c_str(), &end, 10) : -1;
  if (!text || end == text->c_str()) {
    c.verdict = Verdict::kWarn;
    c.found = "cannot read " + where.string();
    c.fix = fix;
    return c;
  }
  c.found = "net.core.rmem_max " + std::to_string(v) + " bytes";
  if (v < kRmemWanted) {
    c.verdict = Verdict::kWarn;
    c.found += ": below 2 MiB, large samples (scans, images) and bursts are dropped by the socket";
    c.fix = fix;
  }
  return c;
}

DoctorCheck check_preempt_rt(const fs::path& root) {
  DoctorCheck c{"preempt-rt", Verdict::kOk, "", ""};
  const auto realtime = read_text(under(root, "/sys/kernel/realtime"));
  const auto version = read_text(under(root, "/proc/version"));
  const std::string kernel = version ? first_line(*version) : std::string("unknown kernel");
  if ((realtime && first_line(*realtime) == "1") || (version && version->find("PREEMPT_RT") != std::string::npos)) {
    c.found = "PREEMPT_RT kernel";
    return c;
  }
  c.verdict = Verdict::kWarn;
  c.found = "not a PREEMPT_RT kernel (" + kernel + "): wake-up latency has a tail of milliseconds";
  c.fix = "sudo apt-get install linux-image-rt-amd64 (linux-image-rt-arm64 on arm64) and reboot into it";
  return c;
}

DoctorCheck check_cpu_dma_latency(const fs::path& root) {
  DoctorCheck c{"cpu-dma-latency", Verdict::kOk, "", ""};
  const auto p = under(root, "/dev/cpu_dma_latency");
  std::error_code ec;
  if (!fs::exists(p, ec)) {
    c.verdict = Verdict::kWarn;
    c.found = p.string() + " does not exist: rackd cannot keep the CPUs out of deep idle states";
    c.fix =
        "a kernel with CONFIG_CPU_IDLE / PM QoS (Debian's have it); in a container, bind-mount /dev/cpu_dma_latency";
    return c;
  }
  if (::access(p.c_str(), W_OK) != 0) {
    c.verdict = Verdict::kWarn;
    c.found = p.string() + " is not writable by this user (" + std::strerror(errno) +
              "): rackd's cpu_dma_latency_us is not held";
    c.fix =
        "as root: echo 'KERNEL==\"cpu_dma_latency\", GROUP=\"realtime\", MODE=\"0660\"' > "
        "/etc/udev/rules.d/99-cpu-dma-latency.rules; udevadm trigger (and be in group realtime)";
    return c;
  }
  c.found = p.string() + " writable";
  return c;
}

DoctorCheck check_clocksource(const fs::path& root) {
  DoctorCheck c{"clocksource", Verdict::kOk, "", ""};
  const auto dir = under(root, "/sys/devices/system/clocksource/clocksource0");
  const auto current = read_text(dir / "current_clocksource");
  if (!current) {
    c.verdict = Verdict::kWarn;
    c.found = "cannot read " + (dir / "current_clocksource").string();
    c.fix = "check with: cat " + (dir / "current_clocksource").string();
    return c;
  }
  const std::string name = first_line(*current);
  c.found = "clock source " + name;
  // These are read in user space (vDSO): clock_gettime costs tens of nanoseconds.
  for (const char* fast : {"tsc", "kvm-clock", "arch_sys_counter", "hyperv_clocksource_tsc_page"}) {
    if (name == fast) return c;
  }
  c.verdict = Verdict::kWarn;
  c.found += ": not read through the vDSO, every clock_gettime is a system call (microseconds)";
  const auto available = read_text(dir / "available_clocksource");
  c.fix = "available: " + (available ? first_line(*available) : std::string("?")) +
          "; if tsc is listed: echo tsc | sudo tee " + (dir / "current_clocksource").string() +
          " (at boot: clocksource=tsc)";
  return c;
}

std::string json_escape(const std::string& s) {
  std::string out;
  for (const char ch : s) {
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (static_cast<unsigned char>(ch) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(ch)));
      out += buf;
    } else {
      out += ch;
    }
  }
  return out;
}

}  // namespace

const char* describe(Verdict v) noexcept {
  switch (v) {
    case Verdict::kOk: return "ok";
    case Verdict::kWarn: return "WARN";
    case Verdict::kFail: return "FAIL";
  }
  return "?";
}

std::vector<DoctorCheck> run_doctor(const DoctorInput& in) {
  const auto limits = read_text(under(in.root, "/proc/self/limits"));
  const auto status = read_text(under(in.root, "/proc/self/status"));
  const auto caps = status ? effective_caps(*status) : std::nullopt;
  return {check_rt_priority(in.root, limits, caps),
          check_memlock(in.root, limits, caps),
          check_multicast_route(in.root, in.multicast_group),
          check_rmem_max(in.root),
          check_preempt_rt(in.root),
          check_cpu_dma_latency(in.root),
          check_clocksource(in.root)};
}

std::string format_doctor(const std::vector<DoctorCheck>& checks) {
  std::string out;
  for (const auto& c : checks) {
    char head[64];
    std::snprintf(head, sizeof head, "%-4s %-16s ", describe(c.verdict), c.name.c_str());
    out += head + c.found + "\n";
    if (!c.fix.empty()) out += std::string(22, ' ') + "fix: " + c.fix + "\n";
  }
  return out;
}

std::string doctor_json(const std::vector<DoctorCheck>& checks) {
  std::string out = "[";
  for (std::size_t i = 0; i < checks.size(); ++i) {
    const auto& c = checks[i];
    out += (i == 0 ? "{" : ",{") + std::string("\"check\":\"") + json_escape(c.name) + "\",\"verdict\":\"" +
           describe(c.verdict) + "\",\"found\":\"" + json_escape(c.found) + "\",\"fix\":\"" + json_escape(c.fix) +
           "\"}";
  }
  return out + "]";
}

}  // namespace rack::tools
