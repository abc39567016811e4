// CPU idle-state latency (PM QoS): while an RT executor runs, CPUs should not enter
// idle states whose exit latency exceeds what its tasks can afford. Writing a latency
// bound to /dev/cpu_dma_latency and keeping the file open holds it; the kernel applies
// the smallest bound of all holders and drops ours when the descriptor closes
// (Documentation/power/pm_qos_interface.rst). cyclictest holds 0 us by default; in a
// VM with cpuidle-haltpoll that roughly halves wake-up latencies (bench/RESULTS.md).
//
// Not real-time safe: construct at start-up.
#pragma once

#include <cstdint>
#include <string>

namespace rack::rt {

class CpuLatencyHold {
 public:
  // Holds the bound `us` (0: stay in the shallowest idle state). A negative value
  // holds nothing. Check active() / error() afterwards.
  explicit CpuLatencyHold(int32_t us) noexcept;
  ~CpuLatencyHold();
  CpuLatencyHold(const CpuLatencyHold&) = delete;
  CpuLatencyHold& operator=(const CpuLatencyHold&) = delete;

  [[nodiscard]] bool active() const noexcept { return fd_ >= 0; }
  [[nodiscard]] int32_t bound_us() const noexcept { return us_; }
  [[nodiscard]] int error() const noexcept { return errno_; }  // 0, or why it could not be held
  // One line for a start-up report: "held at 0 us" or why not.
  [[nodiscard]] std::string describe() const;

 private:
  int fd_ = -1;
  int32_t us_ = -1;
  int errno_ = 0;
};

}  // namespace rack::rt
