#include "rack/rt/capabilities.h"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "rack/rt/thread_birth.h"

namespace rack::rt {

namespace {

void* noop(void*) { return nullptr; }

bool try_fifo_thread() {
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
  pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
  sched_param param{};
  param.sched_priority = 1;
  pthread_attr_setschedparam(&attr, &param);
  pthread_t t;
  const thread_birth::OwnThreads own;  // the probe asks for SCHED_FIFO: not to be placed
  const int rc = pthread_create(&t, &attr, &noop, nullptr);
  pthread_attr_destroy(&attr);
  if (rc != 0) return false;
  pthread_join(t, nullptr);
  return true;
}

std::string read_first_line(const char* path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

}  // namespace

bool parse_cpu_list(const std::string& text, std::vector<int>& out) {
  // The kernel's NR_CPUS is at most 8192: a larger number is no CPU, and a list of more
  // (a range up to INT_MAX, or ranges repeated) would fill memory before it ended.
  constexpr int kMaxCpus = 8192;
  out.clear();
  std::stringstream ss(text);
  std::string part;
  while (std::getline(ss, part, ',')) {
    if (part.empty()) return false;
    const auto dash = part.find('-');
    try {
      std::size_t used = 0;
      if (dash == std::string::npos) {
        const int cpu = std::stoi(part, &used);
        if (used != part.size() || cpu < 0 || cpu >= kMaxCpus || out.size() >= kMaxCpus) return false;
        out.push_back(cpu);
      } else {
        const std::string a = part.substr(0, dash), b = part.substr(dash + 1);
        std::size_t ua = 0, ub = 0;
        const int lo = std::stoi(a, &ua), hi = std::stoi(b, &ub);
        if (ua != a.size() || ub != b.size() || lo < 0 || hi < lo || hi >= kMaxCpus) return false;
        if (out.size() + static_cast<std::size_t>(hi - lo + 1) > kMaxCpus) return false;
        for (int c = lo; c <= hi; ++c) out.push_back(c);
      }
    } catch (const std::exception&) {
      return false;
    }
  }
  return !out.empty();
}

bool RtCapabilities::cpu_online(int cpu) const {
  return std::find(online_cpus.begin(), online_cpus.end(), cpu) != online_cpus.end();
}

std::string RtCapabilities::describe() const {
  std::string s;
  s += std::string("RT scheduling (SCHED_FIFO): ") + (sched_fifo ? "yes" : "NO");
  s += std::string(", memory locking: ") + (memlock ? "yes" : "NO");
  s += std::string(", PREEMPT_RT kernel: ") + (preempt_rt ? "yes" : "NO");
  s += ", online CPUs: " + std::to_string(online_cpus.size());
  s += ", kernel " + kernel;
  return s;
}

RtCapabilities probe_capabilities() {
  RtCapabilities caps;
  caps.sched_fifo = try_fifo_thread();
  rlimit lim{};
  caps.memlock = geteuid() == 0 || (getrlimit(RLIMIT_MEMLOCK, &lim) == 0 && lim.rlim_cur == RLIM_INFINITY);
  utsname u{};
  if (uname(&u) == 0) caps.kernel = std::string(u.release) + " " + u.version;
  caps.preempt_rt = read_first_line("/sys/kernel/realtime") == "1" ||
                    caps.kernel.find("PREEMPT_RT") != std::string::npos;
  if (!parse_cpu_list(read_first_line("/sys/devices/system/cpu/online"), caps.online_cpus)) {
    const long n = sysconf(_SC_NPROCESSORS_ONLN);
    for (long c = 0; c < n; ++c) caps.online_cpus.push_back(static_cast<int>(c));
  }
  return caps;
}

}  // namespace rack::rt
