// Data types and class commands of the demo and test classes (Generator, Monitor,
// Probe). Like every interface header: plain payload types, no heavy includes, so
// tools can decode the data.
//
// Real-time contract: plain data; RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/tims/payload.h"

namespace rack::interfaces {

// Generator: a periodic sine wave with a sample counter.
struct GeneratorData {
  double value = 0.0;   // amplitude * sin(2 pi f t) + offset
  int64_t counter = 0;  // samples since the last ON (or RESET)
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(GeneratorData, value), RACK_FIELD(GeneratorData, counter)};
  }
};
inline constexpr int8_t kGeneratorReset = 21;  // request, no body: counter to 0; reply OK

// Monitor: what a consumer saw of its source's stream.
struct MonitorData {
  uint64_t received = 0;  // samples received since ON
  uint64_t gaps = 0;      // samples missing from the stream (by sequence)
  uint64_t source_sequence = 0;
  double last_value = 0.0;  // the source's last value (Generator data)
  int64_t latency_ns = 0;   // receive time - recording time of the last sample
  int64_t latency_max_ns = 0;
  int64_t real_period_ns = 0;  // the period the source granted
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(MonitorData, received),        RACK_FIELD(MonitorData, gaps),
                      RACK_FIELD(MonitorData, source_sequence), RACK_FIELD(MonitorData, last_value),
                      RACK_FIELD(MonitorData, latency_ns),      RACK_FIELD(MonitorData, latency_max_ns),
                      RACK_FIELD(MonitorData, real_period_ns)};
  }
};

// Probe: counts of its hook calls, so tests see the life cycle from outside.
struct ProbeData {
  int64_t loops = 0;
  int64_t on_calls = 0;
  int64_t off_calls = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ProbeData, loops), RACK_FIELD(ProbeData, on_calls), RACK_FIELD(ProbeData, off_calls)};
  }
};
inline constexpr int8_t kProbeEcho = 21;   // request with an 8-byte body; replied OK with the same body
inline constexpr int8_t kProbeThrow = 22;  // request: command() throws (the component goes to ERROR)

// ModeSwitchDemo: class commands that each do one non-real-time thing inside the
// command handler (a cycle of the command task), so the mode-switch detector reports
// it. Requests without a body unless noted; replied OK after the deed (a crash is
// never replied). See configs/modeswitch_demo.yaml.
inline constexpr int8_t kDemoSyscall = 21;  // write() to /dev/null                          -> SYSCALL
inline constexpr int8_t kDemoFault = 22;    // touch a page that is not resident             -> FAULT
inline constexpr int8_t kDemoAlloc = 23;    // new[] and delete[]                            -> ALLOC (2)
inline constexpr int8_t kDemoPrioInv = 24;  // lock a std::mutex (no priority inheritance)  -> PRIOINV
inline constexpr int8_t kDemoSpin = 25;     // busy for N ms (8-byte body, default 300)      -> WATCHDOG (RLIMIT_RTTIME)
inline constexpr int8_t kDemoOverrun = 26;  // the next loop() overruns by 30 periods        -> WATCHDOG (overrun)
inline constexpr int8_t kDemoDevice = 27;   // write() to a registered RT device (a pipe)    -> nothing
inline constexpr int8_t kDemoCrash = 28;    // write through a null pointer                  -> CRASH (SIGSEGV)
inline constexpr int8_t kDemoAbort = 29;    // std::abort()                                  -> CRASH (SIGABRT)
inline constexpr int8_t
    kDemoLoopSyscall = 30;                // the next loop() makes a write()            -> SYSCALL in the data task
inline constexpr int8_t kDemoSleep = 31;  // usleep(2000) directly, not through rack::rt  -> RUSAGE (with rusage: true)

struct ModeSwitchDemoData {
  int64_t cycles = 0;  // loop() calls since ON
  int64_t deeds = 0;   // class commands carried out
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ModeSwitchDemoData, cycles), RACK_FIELD(ModeSwitchDemoData, deeds)};
  }
};

}  // namespace rack::interfaces
