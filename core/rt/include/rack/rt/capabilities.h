// What this host gives real-time tasks: RT scheduling rights, memory locking, a
// PREEMPT_RT kernel, online CPUs. rackd states these loudly at start.
//
// Real-time contract: not RT-safe (reads /sys, starts a probe thread).
#pragma once

#include <string>
#include <vector>

namespace rack::rt {

struct RtCapabilities {
  bool sched_fifo = false;  // a SCHED_FIFO thread could be created
  bool memlock = false;     // mlockall is allowed (CAP_IPC_LOCK or unlimited RLIMIT_MEMLOCK)
  bool preempt_rt = false;  // /sys/kernel/realtime is 1
  std::string kernel;       // uname release and version
  std::vector<int> online_cpus;
  [[nodiscard]] bool cpu_online(int cpu) const;
  [[nodiscard]] std::string describe() const;
};

[[nodiscard]] RtCapabilities probe_capabilities();

// Parses a kernel CPU list such as "0-3,6,8-9". Returns false on malformed text, on a
// CPU number of 8192 or more (the kernel's NR_CPUS limit) and on more than 8192 CPUs.
bool parse_cpu_list(const std::string& text, std::vector<int>& out);

}  // namespace rack::rt
