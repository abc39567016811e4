#include "netns.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <stdexcept>

#include "process.h"

namespace rack::test {

namespace {

using namespace std::chrono_literals;
constexpr const char* kPrefix = "rkit-";

// The bridge end of host i's veth. (Appending, not "p" + std::to_string(i): GCC 12
// warns falsely (-Wrestrict) on that form.)
std::string port_name(int i) {
  std::string s = "p";
  s += std::to_string(i);
  return s;
}

std::string ip_path() {
  for (const char* p : {"/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"}) {
    if (access(p, X_OK) == 0) return p;
  }
  return "";
}

// Namespaces left by test processes that no longer exist.
void delete_stale(const std::string& ip) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator("/run/netns", ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(kPrefix, 0) != 0) continue;
    const auto dash = name.find('-', 5);
    if (dash == std::string::npos) continue;
    const long pid = std::strtol(name.substr(5, dash - 5).c_str(), nullptr, 10);
    if (pid <= 0 || (kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)) {
      (void)run({ip, "netns", "del", name}, 10s);
    }
  }
}

}  // namespace

std::optional<std::string> NetnsTopology::unsupported_reason() {
  if (geteuid() != 0) return "multi-host tests need root (network namespaces); run ctest as root";
  const std::string ip = ip_path();
  if (ip.empty()) return "multi-host tests need iproute2's ip (apt-get install iproute2)";
  const std::string probe = std::string(kPrefix) + std::to_string(getpid()) + "-probe";
  const RunResult r = run({ip, "netns", "add", probe}, 10s);
  if (r.exit_code != 0) return "network namespaces are not available here: " + r.err;
  (void)run({ip, "netns", "del", probe}, 10s);
  return std::nullopt;
}

void NetnsTopology::ip(const std::vector<std::string>& args) {
  std::vector<std::string> full{ip_path()};
  full.insert(full.end(), args.begin(), args.end());
  const RunResult r = run(full, 20s);
  if (r.exit_code != 0) {
    std::string cmd;
    for (const auto& a : full) cmd += a + " ";
    throw std::runtime_error("'" + cmd + "' failed: " + r.describe());
  }
}

NetnsTopology::NetnsTopology(int hosts) {
  static std::atomic<int> counter{0};
  delete_stale(ip_path());
  prefix_ = std::string(kPrefix) + std::to_string(getpid()) + "-" + std::to_string(counter++);
  switch_ = prefix_ + "-sw";
  try {
    ip({"netns", "add", switch_});
    made_.push_back(switch_);
    ip({"-n", switch_, "link", "set", "lo", "up"});
    ip({"-n", switch_, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0"});
    ip({"-n", switch_, "link", "set", "br0", "up"});
    for (int i = 0; i < hosts; ++i) {
      const std::string ns = prefix_ + "-h" + std::to_string(i);
      const std::string port = port_name(i);
      ip({"netns", "add", ns});
      made_.push_back(ns);
      hosts_.push_back(ns);
      ip({"-n", ns, "link", "set", "lo", "up"});
      ip({"link", "add", "eth0", "netns", ns, "type", "veth", "peer", "name", port, "netns", switch_});
      ip({"-n", switch_, "link", "set", port, "master", "br0"});
      ip({"-n", switch_, "link", "set", port, "up"});
      ip({"-n", ns, "addr", "add", "10.77.0." + std::to_string(i + 1) + "/24", "dev", "eth0"});
      ip({"-n", ns, "link", "set", "eth0", "up"});
      // LCM multicast needs a route, or creating the LCM instance fails.
      ip({"-n", ns, "route", "add", "224.0.0.0/4", "dev", "eth0"});
    }
  } catch (...) {
    for (auto it = made_.rbegin(); it != made_.rend(); ++it) (void)run({ip_path(), "netns", "del", *it}, 10s);
    throw;
  }
}

NetnsTopology::~NetnsTopology() {
  for (auto it = made_.rbegin(); it != made_.rend(); ++it) (void)run({ip_path(), "netns", "del", *it}, 10s);
}

void NetnsTopology::set_link(int i, bool up) { ip({"-n", switch_, "link", "set", port_name(i), up ? "up" : "down"}); }

}  // namespace rack::test
