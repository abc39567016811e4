// Mode-switch detection: what Xenomai's SIGDEBUG told RACK, rebuilt on stock Linux.
//
// A real-time task is "in primary mode" while it runs one cycle (the executor brackets
// a data task's loop() and every command handler with enter_cycle()/leave_cycle()).
// Inside that window, everything that would have made Xenomai relax the task is
// recorded with a reason code and a backtrace:
//
//   SYSCALL   a system call that is not on the allow-list (Syscall User Dispatch: one
//             selector byte per thread, flipped at cycle start and end; the SIGSYS
//             handler records, then re-issues the call itself)
//
// How the SIGSYS handler gets out again: the allowed region given to the kernel is
// glibc's signal restorer (`mov $15,%rax; syscall`, its address read back from the
// kernel after installing the handler), so every rt_sigreturn passes. The handler
// opens the selector while it runs (its own calls, nested handlers, the re-issued
// call pass), re-issues the call with the trapped registers, stores the result in
// the saved RAX and closes the selector again before returning. We keep glibc's
// restorer instead of a trampoline of our own because its CFI describes the signal
// frame: the unwinder walks from the handler into the interrupted code. Calls that
// must run in the thread's own context (rt_sigprocmask, sigaltstack, clone, execve,
// exit, ...) are rewound to their `syscall` instruction and run natively with the
// selector open; the rest of that cycle is not filtered.
//   FAULT     a page fault (a perf software page-fault event with sigtrap: a
//             synchronous SIGTRAP in the faulting thread, at the faulting instruction)
//   ALLOC     malloc/free family or any operator new/delete (the interposers in
//             alloc_hooks.cpp, linked into rackd, check a thread-local flag)
//   PRIOINV   locking a pthread mutex without priority inheritance, or waiting on
//             any mutex longer than a threshold
//   WATCHDOG  a cycle that overran by more than N periods, or a task that kept the CPU
//             past RLIMIT_RTTIME (SIGXCPU in the hogging thread, with its backtrace)
//   NOMLOCK   a task started while the process memory was not locked
//   RUSAGE    getrusage(RUSAGE_THREAD) saw page faults during the cycle, or a voluntary
//             context switch in a cycle that made no framework wait (PI lock, condition
//             wait, sleep); optional second opinion, two system calls per cycle
//   CRASH     SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT in any thread: the report is
//             written synchronously before the signal is re-raised with its default
//             action, so the process still dies with it (and dumps core)
//
// Handlers only copy reason, task, address, time and return addresses into a
// preallocated lock-free ring; a non-RT reporter thread formats them, writes them to
// stderr and to a report file in the crash directory, and hands them to any
// additional ReportSink (GDOS). `rack-backtrace REPORT` symbolizes the file.
//
// Backtraces are taken with libgcc's _Unwind_Backtrace (DWARF CFI, .eh_frame), not by
// walking frame pointers: libc and libstdc++ are built without frame pointers, so an
// FP walk loses exactly the frame we want (the component line that called write() or
// operator new). With glibc >= 2.35 and GCC >= 12 the FDE lookup goes through
// _dl_find_object, which is lock-free and async-signal-safe, and the unwinder itself
// does not allocate; glibc's signal restorer carries CFI for the signal frame, so the
// unwind continues from a handler into the interrupted code. The unwinder is warmed
// up in start() (its one-time initialisation runs outside any handler).
//
// The framework's own RT-safe primitives (rt::PiMutex, rt::PiCondVar, the clock
// sleeps) open a TrustedScope around their futex and clock_nanosleep calls, so they
// cost two byte stores instead of a SIGSYS round trip; everything else a cycle calls
// is trapped and checked against the allow-list.
//
// Architecture: x86-64 for SYSCALL (the re-issue and the register layout); the other
// reasons are portable. What the kernel or the privileges do not allow is skipped with
// a printed reason (start()'s summary).
#pragma once

#include <pthread.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace rack::rt::modeswitch {

enum class Reason : uint8_t {
  kSyscall = 1,
  kFault = 2,
  kAlloc = 3,
  kPrioInv = 4,
  kWatchdog = 5,
  kNoMlock = 6,
  kRusage = 7,
  kCrash = 8,
};
inline constexpr int kReasonCount = 9;  // index 0 unused
// "SYSCALL", "FAULT", ... RT-safe.
[[nodiscard]] const char* reason_name(Reason r) noexcept;
[[nodiscard]] std::optional<Reason> parse_reason(std::string_view name) noexcept;

enum class Mode : uint8_t {
  kOff = 0,    // no detection for this task
  kWarn = 1,   // report and continue
  kAbort = 2,  // report, then the component goes to ERROR (or the process aborts)
};
[[nodiscard]] const char* mode_name(Mode m) noexcept;
[[nodiscard]] std::optional<Mode> parse_mode(std::string_view name) noexcept;

enum class AbortAction : uint8_t {
  kComponent,  // abort mode puts the component in ERROR
  kProcess,    // abort mode writes the report and aborts the process (core dump)
};

// Process-wide settings (the host file's `modeswitch:` block).
struct Config {
  std::string crash_dir = "/var/tmp/rack";  // report files: <crash_dir>/<program>-<pid>.report
  std::string program = "rack";
  Mode default_mode = Mode::kWarn;
  AbortAction abort_action = AbortAction::kComponent;
  bool syscalls = true;
  bool faults = true;
  bool allocations = true;
  bool locks = true;
  bool rusage = false;
  bool crash_handlers = true;
  bool to_stderr = true;
  int64_t lock_wait_ns = 200'000;           // PRIOINV when a mutex wait in a cycle is longer
  uint32_t watchdog_periods = 20;           // WATCHDOG when a cycle overruns by more (0: off)
  int64_t rttime_us = 0;                    // RLIMIT_RTTIME soft limit (0: off)
  std::vector<std::string> allow_syscalls;  // added to the default allow-list
  uint32_t stderr_per_second = 20;          // more reports than this go to the file only
  // Identical reports (same reason, task, component, system call and backtrace) after
  // the first are counted, not written: the first in full, then at most one `repeat`
  // line per this period while it repeats (and at stop), so a fault that repeats each
  // cycle cannot fill a disk (tools/backtrace/README.md). 0: every report in full.
  int64_t repeat_every_ns = 10'000'000'000;
};

// What start() switched on, and why anything was left off.
struct StartResult {
  bool syscalls = false, faults = false, allocations = false, locks = false, crash = false, rttime = false;
  std::string report_path;
  std::vector<std::string> notes;  // "FAULT: skipped: ..." lines
  [[nodiscard]] std::string describe() const;
};

// One report as a sink sees it (valid during the publish() call only).
struct ReportView {
  uint64_t sequence = 0;
  Reason reason = Reason::kSyscall;
  Mode mode = Mode::kWarn;
  int tid = 0;
  int64_t time_ns = 0;                // CLOCK_REALTIME
  std::string_view task;              // "demo:cmd"
  std::string_view component;         // host-file name, "" when not a component task
  std::string_view label;             // "ModeSwitchDemo(0/0)"
  std::string_view detail;            // "write(5, 0x7f.., 12): fd 5 is not a registered RT device"
  std::span<const uintptr_t> frames;  // call-site PCs, innermost first
};

// Where the reporter thread sends reports besides stderr and the report file (the
// GDOS issue adds one). publish() runs on the reporter thread (not RT); it may block
// briefly but should not take long.
class ReportSink {
 public:
  virtual ~ReportSink() = default;
  virtual void publish(const ReportView& report, std::string_view text) = 0;
};

// ---- process life cycle (not RT-safe; main thread) ------------------------------

// Installs the handlers, records the loaded modules (build ids, load addresses),
// opens the report file and starts the reporter thread. Call after plug-ins are
// loaded and after the memory policy, before RT tasks start. Idempotent.
StartResult start(const Config& config);
// Adds a sink; call before or after start(). Not RT-safe.
void add_sink(std::shared_ptr<ReportSink> sink);
// Drains the ring, stops the reporter, removes the report file if it holds no report.
void stop();
[[nodiscard]] bool running() noexcept;

struct Counters {
  uint64_t reports = 0;  // recorded
  uint64_t dropped = 0;  // ring full
  uint64_t by_reason[kReasonCount] = {};
};
[[nodiscard]] Counters counters() noexcept;  // any thread; RT-safe

// ---- tasks ------------------------------------------------------------------------

struct TaskInfo {
  std::string task;       // thread/task name, "demo:cmd"
  std::string component;  // host-file name
  std::string label;      // "ModeSwitchDemo(0/0)"
  uint32_t address = 0;   // TiMS address (opaque here)
  Mode mode = Mode::kWarn;
};

// Registers the calling thread as an RT task: Syscall User Dispatch, the page-fault
// event, the NOMLOCK check. Not RT-safe (call at task start, before the first cycle).
// A no-op when detection is not running or the mode is off.
void attach_current_thread(const TaskInfo& info);
// Undoes attach (call at task end). Not RT-safe.
void detach_current_thread() noexcept;

// RAII attach/detach for a task body.
class TaskAttachment {
 public:
  explicit TaskAttachment(const TaskInfo& info) { attach_current_thread(info); }
  ~TaskAttachment() { detach_current_thread(); }
  TaskAttachment(const TaskAttachment&) = delete;
  TaskAttachment& operator=(const TaskAttachment&) = delete;
};

struct Verdict {
  uint32_t reports = 0;  // recorded during this cycle
  bool abort = false;    // mode abort and something was recorded: the caller fails the cycle
};

// Opens the primary-mode window of one cycle. RT-safe (a few stores; plus a
// getrusage call when rusage checks are on).
void enter_cycle() noexcept;
// Closes it. RT-safe. With AbortAction::kProcess and a violation it does not return.
Verdict leave_cycle() noexcept;
// The executor's periodic loop tells the detector how many periods a cycle missed;
// more than Config::watchdog_periods is a WATCHDOG report. RT-safe.
void note_overrun(uint64_t missed_periods, int64_t cycle_ns) noexcept;

// While alive, system calls of the calling thread are not trapped (the framework's
// own RT-safe primitives use it around futex and clock_nanosleep). `may_block`: the
// call may wait (a PI lock, a condition wait, a sleep), so a voluntary context switch
// in this cycle is expected and RUSAGE does not report it. RT-safe.
class TrustedScope {
 public:
  explicit TrustedScope(bool may_block = false) noexcept;
  ~TrustedScope();
  TrustedScope(const TrustedScope&) = delete;
  TrustedScope& operator=(const TrustedScope&) = delete;

 private:
  char saved_;
};

// A driver opening or closing its device from on()/off() (a serial port, a CAN
// socket): open(), termios and socket set-up block in the kernel and are not
// real-time, but a driver must (re)open its device when it is switched on, and on()
// runs in the component's command task. This scope says "deliberate set-up": its
// system calls are not reported. Use it around the open/close code only, never in
// loop() or command() paths; the command task is blocked for as long as it takes,
// which is why ON is answered only when on() has finished. RT-safe to construct.
class DeviceSetupScope {
 public:
  DeviceSetupScope() noexcept : trusted_(true) {}

 private:
  TrustedScope trusted_;
};

// File descriptors that RT tasks may read, write, ioctl, poll, send and receive on
// (CAN sockets, serial ports). Process-wide. RT-safe (an atomic bit). fd < 4096.
bool register_rt_device(int fd) noexcept;
void unregister_rt_device(int fd) noexcept;

// Syscall number -> name ("write"), nullptr when unknown. RT-safe.
[[nodiscard]] const char* syscall_name(long nr) noexcept;
[[nodiscard]] long syscall_number(std::string_view name) noexcept;  // -1 when unknown

namespace detail {
// Called by the interposers in alloc_hooks.cpp (and by any other allocator
// replacement that wants to keep ALLOC detection working). RT-safe.
enum class HeapCall : uint8_t { kMalloc, kCalloc, kRealloc, kAlignedAlloc, kFree, kNew, kDelete };
void on_heap_call(HeapCall call, std::size_t size) noexcept;
// The real pthread_mutex_lock, with the PRIOINV checks around it.
int checked_mutex_lock(pthread_mutex_t* mutex, int (*real_lock)(pthread_mutex_t*)) noexcept;
}  // namespace detail

}  // namespace rack::rt::modeswitch
