// ModeSwitchDemo's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt):
// the sample type it publishes and its class commands (rack/interfaces/demo.h), each
// of which triggers one mode-switch reason.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/demo.h"

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
