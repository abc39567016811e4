// rackctl doctor: checks what this host needs to run rackd in real time, each check
// with what it found and the fix. The checks read files only (/proc, /sys, /dev below
// `root`), so that a test can give them a fake tree; nothing is changed on the host.
//
// Not RT code: allocates and reads files. Thread-compatible (no shared state).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace rack::tools {

enum class Verdict { kOk, kWarn, kFail };
[[nodiscard]] const char* describe(Verdict v) noexcept;  // "ok", "WARN", "FAIL"

struct DoctorCheck {
  std::string name;  // short key, e.g. "rt-priority"
  Verdict verdict = Verdict::kOk;
  std::string found;  // what was read, with where from
  std::string fix;    // what to do (empty when ok)
};

struct DoctorInput {
  std::filesystem::path root = "/";  // prefix of /proc, /sys and /dev (tests: a fake tree)
  // The multicast group rackctl and rackd use (from the LCM URL), for the route check.
  std::string multicast_group = "239.255.76.67";
};

// The checks, in this order: rt-priority (RLIMIT_RTPRIO / CAP_SYS_NICE), memlock
// (RLIMIT_MEMLOCK / CAP_IPC_LOCK), multicast-route, rmem-max, preempt-rt,
// cpu-dma-latency, clocksource. A file that cannot be read is a WARN that says so.
[[nodiscard]] std::vector<DoctorCheck> run_doctor(const DoctorInput& in);

// The report as text lines: "ok   name  found" and, for WARN/FAIL, "     fix: ...".
[[nodiscard]] std::string format_doctor(const std::vector<DoctorCheck>& checks);

// The report as one JSON array of {"check","verdict","found","fix"}.
[[nodiscard]] std::string doctor_json(const std::vector<DoctorCheck>& checks);

}  // namespace rack::tools
