// ModeSwitchDemo's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt):
// the sample type it publishes and its class commands, each of which triggers one
// mode-switch reason.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/tims/payload.h"

// The payload types (namespace rack::interfaces, as every sample type's, so that code
// naming them did not change when they moved here from components/interfaces).
namespace rack::interfaces {

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

namespace rack::components {

struct ModeSwitchDemoSpinBody {  // SPIN's 8-byte body: how long to spin, ms
  int64_t value = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(ModeSwitchDemoSpinBody, value)}; }
};

inline constexpr DataTypeInfo kModeSwitchDemoType = data_type_info<interfaces::ModeSwitchDemoData>(
    "ModeSwitchDemoData");
inline constexpr DataTypeInfo kModeSwitchDemoSpinBody = data_type_info<ModeSwitchDemoSpinBody>("Int64");
inline constexpr CommandInfo kModeSwitchDemoCommands[] = {
    {"SYSCALL", interfaces::kDemoSyscall, nullptr, "write() to /dev/null -> SYSCALL"},
    {"FAULT", interfaces::kDemoFault, nullptr, "touch a page that is not resident -> FAULT"},
    {"ALLOC", interfaces::kDemoAlloc, nullptr, "new[] and delete[] -> ALLOC"},
    {"PRIOINV", interfaces::kDemoPrioInv, nullptr, "lock a std::mutex -> PRIOINV"},
    {"SPIN", interfaces::kDemoSpin, &kModeSwitchDemoSpinBody, "busy for value ms (0: 300) -> WATCHDOG"},
    {"OVERRUN", interfaces::kDemoOverrun, nullptr, "the next loop() overruns -> WATCHDOG"},
    {"DEVICE", interfaces::kDemoDevice, nullptr, "write() to a registered RT device -> nothing"},
    {"CRASH", interfaces::kDemoCrash, nullptr, "write through a null pointer -> CRASH"},
    {"ABORT", interfaces::kDemoAbort, nullptr, "std::abort() -> CRASH"},
    {"LOOP_SYSCALL", interfaces::kDemoLoopSyscall, nullptr, "the next loop() makes a write() -> SYSCALL"},
    {"SLEEP", interfaces::kDemoSleep, nullptr, "usleep(2000) -> RUSAGE"}};

}  // namespace rack::components
