// Mode-switch detection (see rack/rt/modeswitch.h for the what and the why).
//
// Everything a signal handler or an interposer touches is static and preallocated:
// the task table, the report ring, the module table. Handlers use only lock-free
// atomics, stores into their own thread's slot, the vDSO clock, _Unwind_Backtrace
// (async-signal-safe here, see the header) and raw system calls.
#include "rack/rt/modeswitch.h"

#include <dlfcn.h>
#include <elf.h>
#include <fcntl.h>
#include <link.h>
#include <linux/perf_event.h>
#include <signal.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <sys/syscall.h>
#include <ucontext.h>
#include <unistd.h>
#include <unwind.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <thread>

#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/modeswitch_report.h"
#include "signal_text.h"

#ifndef PR_SET_SYSCALL_USER_DISPATCH
#define PR_SET_SYSCALL_USER_DISPATCH 59
#define PR_SYS_DISPATCH_OFF 0
#define PR_SYS_DISPATCH_ON 1
#endif

// Defined by alloc_hooks.cpp (rack::rt_hooks): tells start() the interposers are there.
extern "C" __attribute__((weak)) void rack_rt_hooks_linked();

namespace rack::rt::modeswitch {

namespace {

// ---------------------------------------------------------------- constants

constexpr char kAllow = 0;                                // SYSCALL_DISPATCH_FILTER_ALLOW
constexpr char kBlock = 1;                                // SYSCALL_DISPATCH_FILTER_BLOCK
constexpr int kSysUserDispatch = 2;                       // si_code of a SUD SIGSYS (asm-generic/siginfo.h)
constexpr int kTrapPerf = 6;                              // si_code of a perf sigtrap SIGTRAP
constexpr uint32_t kTrapPerfAsync = 1;                    // si_perf_flags: delivered late (SIGTRAP was blocked)
constexpr uint64_t kPerfSigData = 0x5241434b4d535731ull;  // "RACKMSW1": our page-fault events
constexpr int kMaxTasks = 256;
constexpr int kMaxFrames = 48;
constexpr uint64_t kRingSize = 128;  // power of two
constexpr int kMaxModules = 512;
constexpr int kMaxFds = 4096;
constexpr int kMaxSyscalls = 512;
constexpr std::size_t kAltStackBytes = 64 * 1024;

struct SyscallEntry {
  long nr;
  const char* name;
};
constexpr SyscallEntry kSyscalls[] = {
#include "syscall_table.inc"
};

// ---------------------------------------------------------------- tasks

struct TaskSlot {
  std::atomic<bool> used{false};
  char task[32] = {};
  char component[32] = {};
  char label[48] = {};
  uint32_t address = 0;
  Mode mode = Mode::kWarn;
  int tid = 0;
  // The Syscall User Dispatch selector: the kernel reads this byte at every system
  // call of the thread. volatile: written here, read by the kernel and our handlers.
  volatile char selector = kAllow;
  bool sud = false;
  int perf_fd = -1;
  void* altstack = nullptr;
  // Written only by the owning thread and its own signal handlers (same thread:
  // volatile and signal fences are enough, no cross-thread ordering needed).
  volatile uint32_t cycle_reports = 0;
  volatile bool xcpu_reported = false;    // one RLIMIT_RTTIME report per cycle
  volatile uint32_t framework_waits = 0;  // TrustedScope(may_block) in this cycle
  rusage ru_start{};
};

TaskSlot g_tasks[kMaxTasks];
// initial-exec: no __tls_get_addr (which may allocate) in handlers and interposers.
__attribute__((tls_model("initial-exec"))) thread_local TaskSlot* t_slot = nullptr;
__attribute__((tls_model("initial-exec"))) thread_local volatile bool t_in_cycle = false;
__attribute__((tls_model("initial-exec"))) thread_local volatile int t_busy = 0;  // detector code on this thread

// ---------------------------------------------------------------- settings
// Written by start() before any task attaches; read-only afterwards (the thread
// start that follows is the synchronisation).

Config g_config;
std::atomic<bool> g_running{false};
bool g_sud_ok = false, g_fault_ok = false, g_alloc_on = false, g_locks_on = false, g_rusage = false;
bool g_rttime_on = false;
uintptr_t g_sud_region = 0;  // glibc's signal restorer: the only place syscalls are never trapped
uint64_t g_allowed[kMaxSyscalls / 64] = {};
uint64_t g_fd_calls[kMaxSyscalls / 64] = {};
std::atomic<uint64_t> g_rt_fds[kMaxFds / 64] = {};
struct sigaction g_old_sigsys {
}, g_old_sigtrap{}, g_old_sigxcpu{};
struct sigaction g_old_crash[32]{};
constexpr int kCrashSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT};
bool g_crash_installed = false;
int g_report_fd = -1;
char g_report_path[512] = {};
char g_exe_path[256] = {};
std::atomic<bool> g_rttime_hit{false};
pid_t g_pid = 0;

// Bounded, always terminated copy. Async-signal-safe.
void copy_text(char* out, std::size_t size, const char* in) noexcept {
  std::size_t k = 0;
  for (; in != nullptr && in[k] != '\0' && k + 1 < size; ++k) out[k] = in[k];
  out[k] = '\0';
}

bool bit(const uint64_t* set, long nr) noexcept {
  return nr >= 0 && nr < kMaxSyscalls && (set[nr / 64] >> (nr % 64) & 1u) != 0;
}
void set_bit(uint64_t* set, long nr) noexcept {
  if (nr >= 0 && nr < kMaxSyscalls) set[nr / 64] |= uint64_t{1} << (nr % 64);
}

// ---------------------------------------------------------------- the ring

struct Record {
  uint64_t sequence = 0;
  int64_t time_ns = 0;
  Reason reason = Reason::kSyscall;
  Mode mode = Mode::kWarn;
  // Copied from the task's slot, so the slot can be reused once its task ended
  // while reports about it still wait in the ring. "" when not an RT task.
  char task[32] = {};
  char component[32] = {};
  char label[48] = {};
  int32_t tid = 0;
  int32_t signo = 0, code = 0;
  int64_t nr = -1;  // syscall number, heap call kind, sub-reason
  uint64_t args[6] = {};
  uint64_t addr = 0;  // fault address, mutex address
  int64_t value = 0;  // size, wait, periods, ...
  int64_t value2 = 0;
  uint16_t frames = 0;
  uintptr_t pc[kMaxFrames] = {};
};

// Vyukov's bounded queue: producers (handlers on any thread) claim a cell with a CAS
// on enqueue_, fill it, then publish it by storing its turn (release); the consumer
// (the reporter, or a crash handler holding g_consumer) reads a cell whose turn says
// it is published (acquire) and hands it back (release).
struct Cell {
  std::atomic<uint64_t> turn{0};
  Record record;
};
Cell g_ring[kRingSize];
std::atomic<uint64_t> g_enqueue{0};
uint64_t g_dequeue = 0;               // owned by whoever holds g_consumer
std::atomic<bool> g_consumer{false};  // the one consumer at a time
std::atomic<uint64_t> g_sequence{0};
std::atomic<uint64_t> g_dropped{0};
std::atomic<uint64_t> g_by_reason[kReasonCount] = {};

void init_ring() noexcept {
  for (uint64_t i = 0; i < kRingSize; ++i) g_ring[i].turn.store(i, std::memory_order_relaxed);
}

Record* claim(uint64_t& pos) noexcept {
  pos = g_enqueue.load(std::memory_order_relaxed);
  for (;;) {
    Cell& cell = g_ring[pos & (kRingSize - 1)];
    const uint64_t turn = cell.turn.load(std::memory_order_acquire);
    const auto diff = static_cast<int64_t>(turn - pos);
    if (diff == 0) {
      // Relaxed CAS: the cell's contents are ordered by its turn, not by enqueue_.
      if (g_enqueue.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) return &cell.record;
    } else if (diff < 0) {
      return nullptr;  // full
    } else {
      pos = g_enqueue.load(std::memory_order_relaxed);
    }
  }
}
void publish_cell(uint64_t pos) noexcept {
  // SYNC POINT: release; the consumer's acquire load of turn sees the record.
  g_ring[pos & (kRingSize - 1)].turn.store(pos + 1, std::memory_order_release);
}
bool pop(Record& out) noexcept {
  Cell& cell = g_ring[g_dequeue & (kRingSize - 1)];
  if (cell.turn.load(std::memory_order_acquire) != g_dequeue + 1) return false;
  std::memcpy(static_cast<void*>(&out), &cell.record, sizeof out);
  cell.turn.store(g_dequeue + kRingSize, std::memory_order_release);  // back to producers
  ++g_dequeue;
  return true;
}

bool try_lock_consumer(int64_t spin_ns) noexcept {
  const int64_t until = monotonic_ns() + spin_ns;
  for (;;) {
    bool expected = false;
    // acquire: the previous holder's g_dequeue and file writes are visible.
    if (g_consumer.compare_exchange_weak(expected, true, std::memory_order_acquire)) return true;
    if (monotonic_ns() > until) return false;
  }
}
void unlock_consumer() noexcept { g_consumer.store(false, std::memory_order_release); }

// ---------------------------------------------------------------- modules

struct Module {
  uintptr_t base = 0;        // load bias (dlpi_addr)
  uintptr_t lo = 0, hi = 0;  // executable segments, absolute
  uint8_t build_id[32] = {};
  uint8_t build_id_len = 0;
  char path[256] = {};
};
Module g_modules[kMaxModules];
std::atomic<int> g_module_count{0};  // entries below it are immutable
int g_modules_written = 0;           // reporter (consumer) only

int find_module(uintptr_t pc) noexcept {
  const int n = g_module_count.load(std::memory_order_acquire);
  for (int i = 0; i < n; ++i) {
    if (pc >= g_modules[i].lo && pc < g_modules[i].hi) return i;
  }
  return -1;
}

int on_phdr(dl_phdr_info* info, size_t, void*) {
  Module m;
  m.base = info->dlpi_addr;
  bool any = false;
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    const ElfW(Phdr)& ph = info->dlpi_phdr[i];
    if (ph.p_type == PT_LOAD && (ph.p_flags & PF_X) != 0) {
      const uintptr_t lo = m.base + ph.p_vaddr, hi = lo + ph.p_memsz;
      if (!any || lo < m.lo) m.lo = lo;
      if (!any || hi > m.hi) m.hi = hi;
      any = true;
    } else if (ph.p_type == PT_NOTE) {
      // Notes: namesz, descsz, type, name (4-aligned), desc (4-aligned).
      const auto* p = reinterpret_cast<const uint8_t*>(m.base + ph.p_vaddr);
      const uint8_t* end = p + ph.p_memsz;
      while (p + 12 <= end) {
        uint32_t namesz, descsz, type;
        std::memcpy(&namesz, p, 4);
        std::memcpy(&descsz, p + 4, 4);
        std::memcpy(&type, p + 8, 4);
        const uint8_t* name = p + 12;
        const uint8_t* desc = name + ((namesz + 3u) & ~3u);
        if (desc + descsz > end) break;
        if (type == NT_GNU_BUILD_ID && namesz == 4 && std::memcmp(name, "GNU", 4) == 0 && descsz <= 32) {
          std::memcpy(m.build_id, desc, descsz);
          m.build_id_len = static_cast<uint8_t>(descsz);
        }
        p = desc + ((descsz + 3u) & ~3u);
      }
    }
  }
  if (!any) return 0;
  const char* name = info->dlpi_name;
  if (name == nullptr || name[0] == '\0') name = g_exe_path;
  copy_text(m.path, sizeof m.path, name);
  const int n = g_module_count.load(std::memory_order_relaxed);
  for (int i = 0; i < n; ++i) {
    if (g_modules[i].base == m.base && std::strcmp(g_modules[i].path, m.path) == 0) return 0;
  }
  if (n >= kMaxModules) return 1;
  g_modules[n] = m;
  // SYNC POINT: release; readers of the count see the entry.
  g_module_count.store(n + 1, std::memory_order_release);
  return 0;
}

// Not async-signal-safe (dl_iterate_phdr takes the loader lock): start() and the
// reporter only. Serialised by g_consumer or by start().
void refresh_modules() { dl_iterate_phdr(&on_phdr, nullptr); }

// Writes everything, or gives up when `fd` stays unwritable for 200 ms (stderr may be
// a pipe nobody reads: a crash handler must not hang on it). Async-signal-safe.
void write_all(int fd, const char* p, std::size_t n) noexcept {
  while (n > 0 && fd >= 0) {
    pollfd pfd{fd, POLLOUT, 0};
    if (::poll(&pfd, 1, 200) == 0) return;
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return;
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

const char* heap_call_name(int64_t kind) noexcept {
  switch (static_cast<detail::HeapCall>(kind)) {
    case detail::HeapCall::kMalloc: return "malloc";
    case detail::HeapCall::kCalloc: return "calloc";
    case detail::HeapCall::kRealloc: return "realloc";
    case detail::HeapCall::kAlignedAlloc: return "aligned allocation";
    case detail::HeapCall::kFree: return "free";
    case detail::HeapCall::kNew: return "operator new";
    case detail::HeapCall::kDelete: return "operator delete";
  }
  return "heap call";
}

const char* signal_name(int sig) noexcept {
  switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGABRT: return "SIGABRT";
    case SIGXCPU: return "SIGXCPU";
    default: return "signal";
  }
}

bool fd_syscall(long nr) noexcept { return bit(g_fd_calls, nr); }

bool rt_fd(int64_t fd) noexcept {
  if (fd < 0 || fd >= kMaxFds) return false;
  const auto u = static_cast<uint64_t>(fd);
  return (g_rt_fds[u / 64].load(std::memory_order_relaxed) >> (u % 64) & 1u) != 0;
}

// One-line description of a record (the "detail:" line).
void describe_record(const Record& r, Text& t) noexcept {
  switch (r.reason) {
    case Reason::kSyscall: {
      const char* name = syscall_name(r.nr);
      if (name != nullptr) t.s(name);
      else t.s("syscall ").i(r.nr);
      t.c('(');
      for (int k = 0; k < 4; ++k) {
        if (k > 0) t.s(", ");
        t.hex(r.args[k]);
      }
      t.s(", ...)");
      if (r.nr == SYS_poll || r.nr == SYS_ppoll) {
        t.s(": a descriptor in its pollfd array is not a registered RT device");  // args[0] is the array
      } else if (fd_syscall(r.nr)) {
        t.s(": fd ").i(static_cast<int64_t>(r.args[0])).s(" is not a registered RT device");
      } else t.s(": not on the real-time allow-list");
      return;
    }
    case Reason::kFault: t.s("page fault at ").hex(r.addr); return;
    case Reason::kAlloc:
      t.s(heap_call_name(r.nr));
      if (r.nr != static_cast<int64_t>(detail::HeapCall::kFree) &&
          r.nr != static_cast<int64_t>(detail::HeapCall::kDelete)) {
        t.c('(').i(r.value).s(" bytes)");
      }
      t.s(" in a real-time cycle");
      return;
    case Reason::kPrioInv:
      if (r.nr == 0) {
        t.s("pthread_mutex_lock(")
            .hex(r.addr)
            .s(") on a mutex without priority inheritance (kind ")
            .hex(static_cast<uint64_t>(r.value))
            .c(')');
      } else {
        t.s("waited ").i(r.value / 1000).s(" us for mutex ").hex(r.addr).s(" (threshold ").i(r.value2 / 1000).s(" us)");
      }
      return;
    case Reason::kWatchdog:
      if (r.nr == 0) {
        t.s("cycle overran by ").i(r.value).s(" periods (took ").i(r.value2 / 1000).s(" us)");
      } else {
        t.s("RLIMIT_RTTIME: ran more than ").i(r.value).s(" us without blocking (SIGXCPU)");
      }
      return;
    case Reason::kNoMlock:
      t.s("memory is not locked (VmLck: ").i(r.value).s(" kB) when the task started: page faults will hit it");
      return;
    case Reason::kRusage:
      t.s("getrusage during the cycle: minor faults +")
          .i(static_cast<int64_t>(r.args[0]))
          .s(", major faults +")
          .i(static_cast<int64_t>(r.args[1]))
          .s(", voluntary context switches +")
          .i(static_cast<int64_t>(r.args[2]));
      return;
    case Reason::kCrash: t.s(signal_name(r.signo)).s(" (si_code ").i(r.code).s(") at address ").hex(r.addr); return;
  }
}

// The report block (file format: rack/rt/modeswitch_report.h).
void format_record(const Record& r, Text& t) noexcept {
  report::ReportLine line;
  line.sequence = r.sequence;
  line.reason = reason_name(r.reason);
  line.mode = mode_name(r.mode);
  line.task = r.task;
  line.component = r.component;
  line.label = r.label;
  line.tid = r.tid;
  line.time_ns = r.time_ns;
  line.has_syscall = r.reason == Reason::kSyscall;
  line.syscall = r.nr;
  line.has_signal = r.reason == Reason::kCrash;
  line.signal = r.signo;
  line.frames = r.frames;
  t.append([&](char* at, std::size_t room) { return report::format(line, at, room); });
  t.append(report::format_detail_start);
  describe_record(r, t);
  t.c('\n');
  for (uint16_t k = 0; k < r.frames; ++k) {
    report::FrameLine frame;
    frame.index = k;
    frame.pc = r.pc[k];
    const int m = find_module(r.pc[k]);
    if (m >= 0) {
      const char* path = g_modules[m].path;
      const char* base = std::strrchr(path, '/');
      frame.module = base != nullptr ? base + 1 : path;
      frame.offset = r.pc[k] - g_modules[m].base;
    }
    t.append([&](char* at, std::size_t room) { return report::format(frame, at, room); });
  }
  t.append([&](char* at, std::size_t room) { return report::format_end(r.sequence, at, room); });
}

void format_module(int index, Text& t) noexcept {
  const Module& m = g_modules[index];
  static constexpr char kDigits[] = "0123456789abcdef";
  char build_id[2 * sizeof m.build_id + 1];
  std::size_t n = 0;
  for (int k = 0; k < m.build_id_len && n + 2 < sizeof build_id; ++k) {
    build_id[n++] = kDigits[m.build_id[k] >> 4];
    build_id[n++] = kDigits[m.build_id[k] & 15u];
  }
  report::ModuleLine line;
  line.id = index;
  line.base = m.base;
  line.lo = m.lo;
  line.hi = m.hi;
  line.build_id = std::string_view(build_id, n);
  line.path = m.path;
  t.append([&](char* at, std::size_t room) { return report::format(line, at, room); });
}

// Writes module lines the file has not seen yet. Consumer only.
void write_new_modules() noexcept {
  const int n = g_module_count.load(std::memory_order_acquire);
  char buf[512];
  for (; g_modules_written < n; ++g_modules_written) {
    Text t(buf, sizeof buf);
    format_module(g_modules_written, t);
    write_all(g_report_fd, t.data(), t.size());
  }
}

// ---------------------------------------------------------------- capture

struct CaptureState {
  uintptr_t* out;
  int max;
  int n;
  int skip;
  uintptr_t signal_pc;  // the interrupted PC when called from a handler, else 0
  bool found;
};

_Unwind_Reason_Code capture_step(_Unwind_Context* ctx, void* arg) {
  auto* st = static_cast<CaptureState*>(arg);
  int exact = 0;
  uintptr_t ip = _Unwind_GetIPInfo(ctx, &exact);
  if (ip == 0) return _URC_END_OF_STACK;
  // A return address points after the call: step back into the call instruction so
  // the symbolizer names the calling line. The interrupted PC of a signal frame is
  // exact (the faulting instruction, or the one after `syscall`).
  if (exact == 0) ip -= 1;
  if (st->signal_pc != 0 && !st->found) {
    if (!(exact != 0 && ip == st->signal_pc)) return _URC_NO_REASON;  // handler and trampoline frames
    st->found = true;
  } else if (st->signal_pc == 0 && st->skip > 0) {
    --st->skip;
    return _URC_NO_REASON;
  }
  st->out[st->n++] = ip;
  return st->n >= st->max ? _URC_NORMAL_STOP : _URC_NO_REASON;
}

__attribute__((noinline)) int capture(uintptr_t* out, int max, int skip, const ucontext_t* uc) noexcept {
  CaptureState st{out, max, 0, skip + 1, 0, false};  // + capture itself
#if defined(__x86_64__)
  if (uc != nullptr) st.signal_pc = static_cast<uintptr_t>(uc->uc_mcontext.gregs[REG_RIP]);
#endif
  _Unwind_Backtrace(&capture_step, &st);
  if (uc != nullptr && !st.found) {
    // The unwinder did not get through the signal frame: keep at least the PC.
    st.n = 0;
    out[st.n++] = st.signal_pc;
  }
  return st.n;
}

int64_t now_realtime() noexcept { return host_time_ns(); }

int current_tid() noexcept {
  const TaskSlot* s = t_slot;
  return s != nullptr ? s->tid : static_cast<int>(::syscall(SYS_gettid));
}

// Fills a record in place (ring cell or the crash handler's own).
__attribute__((noinline)) void fill(Record& r, Reason reason, const ucontext_t* uc, int skip, int64_t nr,
                                    const uint64_t* args, uint64_t addr, int64_t value, int64_t value2) noexcept {
  const TaskSlot* s = t_slot;
  r.sequence = g_sequence.fetch_add(1, std::memory_order_relaxed) + 1;
  r.time_ns = now_realtime();
  r.reason = reason;
  r.mode = s != nullptr ? s->mode : Mode::kWarn;
  copy_text(r.task, sizeof r.task, s != nullptr ? s->task : "");
  copy_text(r.component, sizeof r.component, s != nullptr ? s->component : "");
  copy_text(r.label, sizeof r.label, s != nullptr ? s->label : "");
  r.tid = current_tid();
  r.signo = 0;
  r.code = 0;
  r.nr = nr;
  for (int k = 0; k < 6; ++k) r.args[k] = args != nullptr ? args[k] : 0;
  r.addr = addr;
  r.value = value;
  r.value2 = value2;
  r.frames = static_cast<uint16_t>(capture(r.pc, kMaxFrames, skip + 1, uc));
}

// Records one report into the ring. Async-signal-safe. skip: detector frames above.
__attribute__((noinline)) void record(Reason reason, const ucontext_t* uc, int skip, int64_t nr, const uint64_t* args,
                                      uint64_t addr, int64_t value, int64_t value2 = 0) noexcept {
  t_busy = t_busy + 1;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  g_by_reason[static_cast<int>(reason)].fetch_add(1, std::memory_order_relaxed);
  if (TaskSlot* s = t_slot) s->cycle_reports = s->cycle_reports + 1;
  uint64_t pos = 0;
  if (Record* r = claim(pos)) {
    fill(*r, reason, uc, skip + 1, nr, args, addr, value, value2);
    publish_cell(pos);
  } else {
    g_dropped.fetch_add(1, std::memory_order_relaxed);
  }
  std::atomic_signal_fence(std::memory_order_seq_cst);
  t_busy = t_busy - 1;
}

// ---------------------------------------------------------------- reporter output

std::mutex g_sinks_mutex;  // reporter thread and add_sink() (both non-RT)
std::vector<std::shared_ptr<ReportSink>> g_sinks;
uint64_t g_written = 0;             // reports written to the file (consumer only)
int64_t g_stderr_window_start = 0;  // rate limit (consumer only)
uint32_t g_stderr_in_window = 0;
uint64_t g_stderr_suppressed = 0;

// Aggregation of identical reports (Config::repeat_every_ns). Consumer only: a fixed
// table, no allocation. Reports of sites beyond kMaxRepeatSites are written in full.
struct RepeatSite {
  uint64_t key = 0;      // report_key(); 0: free
  uint64_t first = 0;    // the sequence number of the report written in full
  uint64_t pending = 0;  // identical reports since the last line about it
  uint64_t total = 0;    // all of them, the first included
  int64_t due_ns = 0;    // monotonic: the next repeat line no earlier than this
};
constexpr std::size_t kMaxRepeatSites = 1024;
RepeatSite g_repeat_sites[kMaxRepeatSites];
std::size_t g_repeat_site_count = 0;

// What makes two reports the same: reason, system call (or heap call kind), task,
// component and the call sites (FNV-1a). Sizes and addresses of data may differ.
uint64_t report_key(const Record& r) noexcept {
  uint64_t h = 14695981039346656037ull;
  const auto mix = [&h](const void* p, std::size_t n) noexcept {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  };
  mix(&r.reason, sizeof r.reason);
  mix(&r.nr, sizeof r.nr);
  mix(r.task, ::strnlen(r.task, sizeof r.task));
  mix(r.component, ::strnlen(r.component, sizeof r.component));
  mix(r.pc, r.frames * sizeof r.pc[0]);
  return h | 1u;  // never 0 (a free entry)
}

// True when `r` repeats a report already written (then counted only).
bool counted_as_repeat(const Record& r) noexcept {
  if (g_config.repeat_every_ns <= 0 || r.reason == Reason::kCrash) return false;
  const uint64_t key = report_key(r);
  for (std::size_t i = 0; i < g_repeat_site_count; ++i) {
    RepeatSite& s = g_repeat_sites[i];
    if (s.key != key) continue;
    ++s.pending;
    ++s.total;
    return true;
  }
  if (g_repeat_site_count < kMaxRepeatSites) {
    g_repeat_sites[g_repeat_site_count++] = RepeatSite{key, r.sequence, 0, 1,
                                                       monotonic_ns() + g_config.repeat_every_ns};
  }
  return false;
}

// `repeat FIRST count=N total=T time_ns=...` for each site with repeats whose period
// is over (`all`: every one, at stop). Consumer only.
void write_repeats(bool all) noexcept {
  const int64_t now = monotonic_ns();
  for (std::size_t i = 0; i < g_repeat_site_count; ++i) {
    RepeatSite& s = g_repeat_sites[i];
    if (s.pending == 0 || (!all && now < s.due_ns)) continue;
    char buf[256];
    Text t(buf, sizeof buf);
    const report::RepeatLine line{s.first, s.pending, s.total, now_realtime()};
    t.append([&](char* at, std::size_t room) { return report::format(line, at, room); });
    write_all(g_report_fd, t.data(), t.size());
    if (g_config.to_stderr) {
      char head[384];
      Text h(head, sizeof head);
      h.s("rack: MODE SWITCH report ")
          .u(s.first)
          .s(" repeated ")
          .u(s.pending)
          .s(" more time(s), ")
          .u(s.total)
          .s(" in all");
      if (g_report_fd >= 0) h.s(" -- symbolize: rack-backtrace ").s(g_report_path);
      h.c('\n');
      write_all(STDERR_FILENO, h.data(), h.size());
    }
    s.pending = 0;
    s.due_ns = now + g_config.repeat_every_ns;
  }
}

// Writes one record to the file, stderr and (when `sinks`) the other sinks.
// Async-signal-safe when sinks is false (crash path: every record in full).
void emit(const Record& r, bool sinks) noexcept {
  static char buf[8192];  // consumer only (g_consumer held)
  Text t(buf, sizeof buf);
  format_record(r, t);
  const bool repeat = sinks && counted_as_repeat(r);
  if (!repeat) {
    write_new_modules();
    write_all(g_report_fd, t.data(), t.size());
    ++g_written;
  }
  if (g_config.to_stderr && !repeat) {
    const int64_t now = monotonic_ns();
    if (now - g_stderr_window_start > kNsPerSec) {
      g_stderr_window_start = now;
      g_stderr_in_window = 0;
    }
    if (r.reason == Reason::kCrash || g_stderr_in_window < g_config.stderr_per_second) {
      ++g_stderr_in_window;
      char head[768];
      Text h(head, sizeof head);
      h.s("rack: MODE SWITCH ").s(reason_name(r.reason));
      if (r.reason == Reason::kCrash) h.s(" (the process dies with the signal)");
      if (g_report_fd >= 0) h.s(" -- symbolize: rack-backtrace ").s(g_report_path);
      if (g_stderr_suppressed > 0) {
        h.s(" (").u(g_stderr_suppressed).s(" earlier reports went to the file only)");
        g_stderr_suppressed = 0;
      }
      h.c('\n');
      write_all(STDERR_FILENO, h.data(), h.size());
      write_all(STDERR_FILENO, t.data(), t.size());
    } else {
      ++g_stderr_suppressed;
    }
  }
  if (!sinks) return;
  char detail[512];
  Text d(detail, sizeof detail);
  describe_record(r, d);
  ReportView v;
  v.sequence = r.sequence;
  v.reason = r.reason;
  v.mode = r.mode;
  v.tid = r.tid;
  v.time_ns = r.time_ns;
  v.task = r.task[0] != '\0' ? std::string_view(r.task) : std::string_view("-");
  v.component = std::string_view(r.component);
  v.label = std::string_view(r.label);
  v.detail = d.view();
  v.frames = std::span<const uintptr_t>(r.pc, r.frames);
  std::lock_guard lock(g_sinks_mutex);
  for (const auto& sink : g_sinks) {
    try {
      sink->publish(v, t.view());
    } catch (...) {
      // A failing sink must not stop the reporter.
    }
  }
}

// Drains the ring (consumer lock held). `sinks`: false from a crash handler.
void drain_locked(bool sinks) noexcept {
  static Record r;  // consumer only
  while (pop(r)) {
    if (sinks) {
      // New plug-in code in a backtrace: record its module first (not signal-safe,
      // hence only on the reporter thread).
      for (uint16_t k = 0; k < r.frames; ++k) {
        if (find_module(r.pc[k]) < 0) {
          refresh_modules();
          break;
        }
      }
    }
    emit(r, sinks);
    if (r.reason == Reason::kWatchdog && r.nr == 1) g_rttime_hit.store(true, std::memory_order_relaxed);
  }
  if (sinks) write_repeats(false);
}

void drain() {
  if (!try_lock_consumer(50 * kNsPerMs)) return;
  drain_locked(true);
  unlock_consumer();
  if (g_rttime_hit.exchange(false, std::memory_order_relaxed) && g_rttime_on) {
    // The kernel raises the soft limit by a second at each SIGXCPU: put it back.
    const rlimit lim{static_cast<rlim_t>(g_config.rttime_us), RLIM_INFINITY};
    setrlimit(RLIMIT_RTTIME, &lim);
  }
}

std::thread g_reporter;
std::mutex g_reporter_mutex;
std::condition_variable g_reporter_cv;
bool g_reporter_stop = false;

void reporter_main() {
  pthread_setname_np(pthread_self(), "rack-reporter");
  std::unique_lock lock(g_reporter_mutex);
  while (!g_reporter_stop) {
    // Handlers cannot wake anyone safely from every context: poll every 20 ms.
    g_reporter_cv.wait_for(lock, std::chrono::milliseconds(20));
    lock.unlock();
    drain();
    lock.lock();
  }
}

// ---------------------------------------------------------------- handlers

#if defined(__x86_64__)
long raw_syscall6(long nr, uint64_t a0, uint64_t a1, uint64_t a2, uint64_t a3, uint64_t a4, uint64_t a5) noexcept {
  long ret;
  register uint64_t r10 asm("r10") = a3;
  register uint64_t r8 asm("r8") = a4;
  register uint64_t r9 asm("r9") = a5;
  asm volatile("syscall"
               : "=a"(ret)
               : "a"(nr), "D"(a0), "S"(a1), "d"(a2), "r"(r10), "r"(r8), "r"(r9)
               : "rcx", "r11", "memory");
  return ret;
}
#endif

void chain(const struct sigaction& old, int sig, siginfo_t* info, void* ctx) noexcept {
  if ((old.sa_flags & SA_SIGINFO) != 0 && old.sa_sigaction != nullptr) {
    old.sa_sigaction(sig, info, ctx);
  } else if (old.sa_handler != SIG_IGN && old.sa_handler != SIG_DFL && old.sa_handler != nullptr) {
    old.sa_handler(sig);
  } else if (old.sa_handler == SIG_DFL) {
    signal(sig, SIG_DFL);
    ::syscall(SYS_tgkill, getpid(), ::syscall(SYS_gettid), sig);
  }
}

bool syscall_allowed(long nr, const uint64_t* a) noexcept {
  if (bit(g_allowed, nr)) return true;
  if (!fd_syscall(nr)) return false;
  if (nr == SYS_poll || nr == SYS_ppoll) {
    // Every descriptor in the pollfd array must be an RT device. The array is the
    // caller's and may be a bad pointer (the kernel would say EFAULT): read it with
    // process_vm_readv, which fails instead of faulting in this handler.
    struct {
      int fd;
      short events, revents;
    } fds[64];
    const uint64_t n = a[1];
    if (n == 0 || n > 64) return false;
    const iovec local{fds, n * sizeof fds[0]};
    const iovec remote{reinterpret_cast<void*>(a[0]), n * sizeof fds[0]};
    if (process_vm_readv(g_pid, &local, 1, &remote, 1, 0) != static_cast<ssize_t>(local.iov_len)) return false;
    for (uint64_t k = 0; k < n; ++k) {
      if (!rt_fd(fds[k].fd)) return false;
    }
    return true;
  }
  return rt_fd(static_cast<int64_t>(static_cast<int>(a[0])));
}

// System calls that must run in the thread's own context, not re-issued from the
// handler: they change the signal state or the stack (the sigreturn after the
// handler would undo or break them), or never return.
bool run_natively(long nr) noexcept {
#if defined(__x86_64__)
  switch (nr) {
    case SYS_rt_sigreturn:
    case SYS_rt_sigprocmask:
    case SYS_rt_sigsuspend:
    case SYS_sigaltstack:
    case SYS_clone:
    case SYS_clone3:
    case SYS_fork:
    case SYS_vfork:
    case SYS_execve:
    case SYS_execveat:
    case SYS_exit:
    case SYS_exit_group:
    case SYS_arch_prctl: return true;
    default: return false;
  }
#else
  (void)nr;
  return true;
#endif
}

void on_sigsys(int sig, siginfo_t* info, void* ctx) {
  auto* uc = static_cast<ucontext_t*>(ctx);
  TaskSlot* s = t_slot;
  if (info->si_code != kSysUserDispatch || s == nullptr) {
    chain(g_old_sigsys, sig, info, ctx);
    return;
  }
#if defined(__x86_64__)
  const int saved_errno = errno;
  const char saved = s->selector;
  s->selector = kAllow;  // our own system calls (and nested handlers') pass
  // Detector code from here on: a page fault in this handler (its stack frame on a
  // fresh page) is ours, not the task's.
  const bool nested = t_busy != 0;
  t_busy = t_busy + 1;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  greg_t* g = uc->uc_mcontext.gregs;
  const long nr = info->si_syscall;
  const uint64_t a[6] = {static_cast<uint64_t>(g[REG_RDI]), static_cast<uint64_t>(g[REG_RSI]),
                         static_cast<uint64_t>(g[REG_RDX]), static_cast<uint64_t>(g[REG_R10]),
                         static_cast<uint64_t>(g[REG_R8]),  static_cast<uint64_t>(g[REG_R9])};
  if (t_in_cycle && !nested && !syscall_allowed(nr, a)) record(Reason::kSyscall, uc, 0, nr, a, 0, 0);
  if (run_natively(nr)) {
    // Back to the `syscall` instruction with the selector open: it runs as if never
    // trapped. The rest of this cycle is not filtered; the next cycle re-arms.
    g[REG_RIP] -= 2;
    g[REG_RAX] = nr;
    t_busy = t_busy - 1;
    errno = saved_errno;
    return;
  }
  // The re-issued call is the task's own again: a fault in the kernel on its behalf
  // (copy_from_user) is the task's.
  t_busy = t_busy - 1;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  g[REG_RAX] = raw_syscall6(nr, a[0], a[1], a[2], a[3], a[4], a[5]);
  std::atomic_signal_fence(std::memory_order_seq_cst);
  errno = saved_errno;
  // Closing again before the return: the sigreturn comes from glibc's restorer, the
  // one region Syscall User Dispatch never traps.
  s->selector = saved;
#else
  (void)uc;
  chain(g_old_sigsys, sig, info, ctx);
#endif
}

void on_sigtrap(int sig, siginfo_t* info, void* ctx) {
  // si_perf_data and si_perf_flags follow si_addr in the kernel's siginfo; glibc 2.36
  // does not name them.
  uint64_t data = 0;
  uint32_t flags = 0;
  std::memcpy(&data, reinterpret_cast<const char*>(info) + 24, sizeof data);
  std::memcpy(&flags, reinterpret_cast<const char*>(info) + 36, sizeof flags);
  if (info->si_code != kTrapPerf || data != kPerfSigData) {
    chain(g_old_sigtrap, sig, info, ctx);
    return;
  }
  TaskSlot* s = t_slot;
  if (s == nullptr || !t_in_cycle || t_busy != 0 || (flags & kTrapPerfAsync) != 0) return;
  t_busy = t_busy + 1;  // a fault of this handler's own frame is not the task's
  std::atomic_signal_fence(std::memory_order_seq_cst);
  const int saved_errno = errno;
  const char saved = s->selector;
  s->selector = kAllow;
  record(Reason::kFault, static_cast<ucontext_t*>(ctx), 0, -1, nullptr, reinterpret_cast<uintptr_t>(info->si_addr), 0);
  s->selector = saved;
  errno = saved_errno;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  t_busy = t_busy - 1;
}

void on_sigxcpu(int, siginfo_t*, void* ctx) {
  TaskSlot* s = t_slot;
  // A non-RT thread: RLIMIT_RTTIME is about RT tasks. Once per cycle: the kernel
  // repeats SIGXCPU while the task keeps the CPU.
  if (s == nullptr || t_busy != 0 || s->xcpu_reported) return;
  s->xcpu_reported = true;
  const int saved_errno = errno;
  const char saved = s->selector;
  s->selector = kAllow;
  record(Reason::kWatchdog, static_cast<ucontext_t*>(ctx), 0, 1, nullptr, 0, g_config.rttime_us);
  s->selector = saved;
  errno = saved_errno;
}

std::atomic<int> g_crashing_tid{0};

void on_crash(int sig, siginfo_t* info, void* ctx) {
  if (TaskSlot* s = t_slot) s->selector = kAllow;
  t_busy = t_busy + 1;
  const int tid = static_cast<int>(::syscall(SYS_gettid));
  // One crash report at a time; a second thread crashing meanwhile waits (bounded).
  int expected = 0;
  const int64_t until = monotonic_ns() + 2 * kNsPerSec;
  while (!g_crashing_tid.compare_exchange_weak(expected, tid, std::memory_order_acquire) && expected != tid &&
         monotonic_ns() < until) {
    expected = 0;
  }
  {
    // First a line that needs no unwinding: if the stack is too broken to unwind,
    // this is what is left.
    char line[160];
    Text t(line, sizeof line);
    t.s("rack: CRASH ").s(signal_name(sig)).s(" at address ").hex(reinterpret_cast<uintptr_t>(info->si_addr));
    t.s(" in thread ").i(tid).s(": writing the report\n");
    write_all(STDERR_FILENO, t.data(), t.size());
  }
  static Record r;  // under g_crashing_tid
  fill(r, Reason::kCrash, static_cast<ucontext_t*>(ctx), 0, -1, nullptr, reinterpret_cast<uintptr_t>(info->si_addr), 0,
       0);
  r.signo = sig;
  r.code = info->si_code;
  if (try_lock_consumer(200 * kNsPerMs)) {
    drain_locked(false);  // what happened before the crash first
    emit(r, false);
    unlock_consumer();
  } else {
    emit(r, false);  // the reporter is stuck (or crashed holding the lock): write anyway
  }
  g_by_reason[static_cast<int>(Reason::kCrash)].fetch_add(1, std::memory_order_relaxed);
  // Die with the original signal: default action, and for a signal that was sent
  // (kill, raise, abort) send it again; a fault re-executes its instruction.
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  sigaction(sig, &dfl, nullptr);
  if (info->si_code <= 0) ::syscall(SYS_tgkill, getpid(), tid, sig);
}

void install(int sig, void (*fn)(int, siginfo_t*, void*), int extra_flags, struct sigaction* old) {
  // Already ours (start() after stop()): keep the handler saved the first time, or
  // chaining would call ourselves.
  struct sigaction current {};
  if (sigaction(sig, nullptr, &current) == 0 && (current.sa_flags & SA_SIGINFO) != 0 && current.sa_sigaction == fn) {
    return;
  }
  struct sigaction sa {};
  sa.sa_sigaction = fn;
  sa.sa_flags = SA_SIGINFO | SA_RESTART | extra_flags;
  sigemptyset(&sa.sa_mask);
  sigaction(sig, &sa, old);
}

// ---------------------------------------------------------------- set-up helpers

int64_t vm_locked_kib() {
  const int fd = ::open("/proc/self/status", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  char buf[4096];
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  if (n <= 0) return -1;
  buf[n] = '\0';
  const char* p = std::strstr(buf, "VmLck:");
  return p != nullptr ? std::strtoll(p + 6, nullptr, 10) : -1;
}

int open_page_fault_event() {
  perf_event_attr a{};
  a.size = sizeof a;
  a.type = PERF_TYPE_SOFTWARE;
  a.config = PERF_COUNT_SW_PAGE_FAULTS;
  a.sample_period = 1;
  a.sample_type = PERF_SAMPLE_ADDR;  // the fault address reaches si_addr
  a.sigtrap = 1;
  a.remove_on_exec = 1;  // the kernel requires it with sigtrap
  a.sig_data = kPerfSigData;
  return static_cast<int>(::syscall(SYS_perf_event_open, &a, 0, -1, -1, PERF_FLAG_FD_CLOEXEC));
}

// The address of glibc's signal restorer, read back from the kernel after
// installing a handler with glibc's sigaction (which fills it in).
uintptr_t find_restorer(int sig) {
#if defined(__x86_64__)
  struct KernelSigaction {
    void* handler;
    unsigned long flags;
    void* restorer;
    uint64_t mask;
  } k{};
  if (::syscall(SYS_rt_sigaction, sig, nullptr, &k, 8) != 0 || k.restorer == nullptr) return 0;
  // mov $15,%rax; syscall
  static constexpr uint8_t kExpected[] = {0x48, 0xc7, 0xc0, 0x0f, 0x00, 0x00, 0x00, 0x0f, 0x05};
  if (std::memcmp(k.restorer, kExpected, sizeof kExpected) != 0) return 0;
  return reinterpret_cast<uintptr_t>(k.restorer);
#else
  (void)sig;
  return 0;
#endif
}

void build_allow_lists() {
  std::memset(g_allowed, 0, sizeof g_allowed);
  std::memset(g_fd_calls, 0, sizeof g_fd_calls);
  // Calls an RT task makes by design: waiting and waking (futex), periodic sleep,
  // clocks, and harmless identity calls.
  for (const char* n :
       {"futex", "futex_waitv", "clock_nanosleep", "clock_gettime", "clock_getres", "gettimeofday", "time",
        "sched_yield", "getpid", "gettid", "getcpu", "rt_sigreturn", "restart_syscall", "getrusage"}) {
    set_bit(g_allowed, syscall_number(n));
  }
  // Device I/O: allowed on file descriptors registered as RT devices.
  for (const char* n : {"read", "write", "pread64", "pwrite64", "readv", "writev", "ioctl", "poll", "ppoll", "sendto",
                        "recvfrom", "sendmsg", "recvmsg", "sendmmsg", "recvmmsg", "epoll_wait", "epoll_pwait"}) {
    set_bit(g_fd_calls, syscall_number(n));
  }
  for (const auto& n : g_config.allow_syscalls) set_bit(g_allowed, syscall_number(n));
}

}  // namespace

// ---------------------------------------------------------------- public

const char* reason_name(Reason r) noexcept {
  switch (r) {
    case Reason::kSyscall: return "SYSCALL";
    case Reason::kFault: return "FAULT";
    case Reason::kAlloc: return "ALLOC";
    case Reason::kPrioInv: return "PRIOINV";
    case Reason::kWatchdog: return "WATCHDOG";
    case Reason::kNoMlock: return "NOMLOCK";
    case Reason::kRusage: return "RUSAGE";
    case Reason::kCrash: return "CRASH";
  }
  return "UNKNOWN";
}

std::optional<Reason> parse_reason(std::string_view name) noexcept {
  for (int k = 1; k < kReasonCount; ++k) {
    if (name == reason_name(static_cast<Reason>(k))) return static_cast<Reason>(k);
  }
  return std::nullopt;
}

const char* mode_name(Mode m) noexcept {
  switch (m) {
    case Mode::kOff: return "off";
    case Mode::kWarn: return "warn";
    case Mode::kAbort: return "abort";
  }
  return "unknown";
}

std::optional<Mode> parse_mode(std::string_view name) noexcept {
  if (name == "off") return Mode::kOff;
  if (name == "warn") return Mode::kWarn;
  if (name == "abort") return Mode::kAbort;
  return std::nullopt;
}

const char* syscall_name(long nr) noexcept {
  for (const auto& e : kSyscalls) {
    if (e.nr == nr) return e.name;
  }
  return nullptr;
}

long syscall_number(std::string_view name) noexcept {
  for (const auto& e : kSyscalls) {
    if (name == e.name) return e.nr;
  }
  return -1;
}

std::string StartResult::describe() const {
  std::string s = "mode-switch detection:";
  auto item = [&s](const char* what, bool on) { s += std::string(" ") + what + (on ? " on," : " OFF,"); };
  item("SYSCALL", syscalls);
  item("FAULT", faults);
  item("ALLOC", allocations);
  item("PRIOINV", locks);
  item("crash reports", crash);
  item("RLIMIT_RTTIME", rttime);
  s += " reports to " + (report_path.empty() ? std::string("stderr only") : report_path);
  for (const auto& n : notes) s += "\n  " + n;
  return s;
}

StartResult start(const Config& config) {
  StartResult result;
  if (g_running.load(std::memory_order_acquire)) {
    result.notes.push_back("already running");
    return result;
  }
  g_config = config;
  g_pid = getpid();
  init_ring();
  build_allow_lists();
  for (const auto& n : config.allow_syscalls) {
    if (syscall_number(n) < 0) result.notes.push_back("allow_syscalls: unknown system call '" + n + "' (ignored)");
  }
  const ssize_t len = ::readlink("/proc/self/exe", g_exe_path, sizeof g_exe_path - 1);
  if (len > 0) g_exe_path[len] = '\0';
  refresh_modules();

  // The report file: created now so a crash handler can write to it.
  if (!config.crash_dir.empty()) {
    std::string dir;
    for (std::size_t k = 0; k <= config.crash_dir.size(); ++k) {  // mkdir -p
      if (k == config.crash_dir.size() || (config.crash_dir[k] == '/' && k > 0)) {
        dir = config.crash_dir.substr(0, k);
        ::mkdir(dir.c_str(), 0755);
      }
    }
    const std::string path = config.crash_dir + "/" + config.program + "-" + std::to_string(getpid()) + ".report";
    g_report_fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
    if (g_report_fd < 0) {
      const int e = errno;
      // A user without write access to the default /var/tmp/rack (not root): say how to choose another.
      result.notes.push_back("report file " + path + ": " + std::strerror(e) +
                             " (reports go to stderr only; rackd --crash-dir DIR or the host file's modeswitch: "
                             "crash_dir: names a folder this user may write)");
    } else {
      copy_text(g_report_path, sizeof g_report_path, path.c_str());
      result.report_path = path;
      char head[512];
      Text t(head, sizeof head);
      report::HeaderLine line;
      line.program = config.program;
      line.pid = getpid();
      line.start_ns = now_realtime();
      line.exe = g_exe_path;
      t.append([&](char* at, std::size_t room) { return report::format(line, at, room); });
      write_all(g_report_fd, t.data(), t.size());
      g_modules_written = 0;
      write_new_modules();
      g_written = 0;
    }
  }

  // Warm the unwinder up here: its one-time initialisation must not run in a handler.
  uintptr_t warm[8];
  (void)capture(warm, 8, 0, nullptr);

  // SYSCALL: Syscall User Dispatch.
  if (config.syscalls && kThreadSanitizer) {
    // TSan's runtime makes raw system calls of its own inside a cycle (around every
    // signal it delivers, in its interceptors): they would be reported as the task's.
    result.notes.push_back("SYSCALL: skipped: ThreadSanitizer build (its runtime makes system calls of its own)");
  } else if (config.syscalls) {
#if defined(__x86_64__)
    install(SIGSYS, &on_sigsys, SA_NODEFER, &g_old_sigsys);
    g_sud_region = find_restorer(SIGSYS);
    if (g_sud_region == 0) {
      result.notes.push_back("SYSCALL: skipped: glibc's signal restorer is not the expected code");
    } else {
      static volatile char probe_selector = kAllow;
      if (prctl(PR_SET_SYSCALL_USER_DISPATCH, PR_SYS_DISPATCH_ON, g_sud_region, 16,
                const_cast<char*>(&probe_selector)) != 0) {
        result.notes.push_back(std::string("SYSCALL: skipped: Syscall User Dispatch unavailable (") +
                               std::strerror(errno) + "; needs Linux >= 5.11 with CONFIG_GENERIC_ENTRY)");
      } else {
        prctl(PR_SET_SYSCALL_USER_DISPATCH, PR_SYS_DISPATCH_OFF, 0, 0, 0);
        g_sud_ok = true;
      }
    }
    if (!g_sud_ok) sigaction(SIGSYS, &g_old_sigsys, nullptr);
#else
    result.notes.push_back("SYSCALL: skipped: only implemented for x86-64");
#endif
  }
  // FAULT: perf page-fault events with sigtrap.
  if (config.faults && kThreadSanitizer) {
    // Every first touch of memory also faults in TSan's shadow of it, and stacks are
    // not pre-faulted there (memory.h): faults inside a cycle are TSan's.
    result.notes.push_back("FAULT: skipped: ThreadSanitizer build (its shadow memory faults in on first touch)");
  } else if (config.faults) {
    const int fd = open_page_fault_event();
    if (fd < 0) {
      const int e = errno;
      std::string why = e == EINVAL ? "the kernel lacks perf_event_attr.sigtrap (Linux >= 5.13)"
                        : (e == EACCES || e == EPERM)
                            ? "perf events not permitted (needs CAP_PERFMON or kernel.perf_event_paranoid <= 1)"
                            : std::strerror(e);
      result.notes.push_back("FAULT: skipped: " + why);
    } else {
      ::close(fd);
      install(SIGTRAP, &on_sigtrap, SA_NODEFER, &g_old_sigtrap);
      g_fault_ok = true;
    }
  }
  g_alloc_on = config.allocations;
  g_locks_on = config.locks;
  g_rusage = config.rusage;
  if (kThreadSanitizer) {
    result.notes.push_back("NOMLOCK: skipped: ThreadSanitizer build (memory is not locked there by design)");
  }
  if (config.rusage && kThreadSanitizer) {
    result.notes.push_back("RUSAGE: minor faults not counted: ThreadSanitizer build (its shadow memory faults in)");
  }
  // The interposers are linked into the program (rack::rt_hooks); without them
  // (a sanitizer build, a program that did not link them) nothing calls the hooks.
  const bool hooks = &rack_rt_hooks_linked != nullptr;
  if (!hooks && (config.allocations || config.locks)) {
    result.notes.push_back(
        "ALLOC, PRIOINV: skipped: the program is not linked with rack::rt_hooks "
        "(the interposers; left out of sanitizer builds)");
  }
  if (config.rttime_us > 0) {
    install(SIGXCPU, &on_sigxcpu, 0, &g_old_sigxcpu);
    const rlimit lim{static_cast<rlim_t>(config.rttime_us), RLIM_INFINITY};
    if (setrlimit(RLIMIT_RTTIME, &lim) != 0) {
      result.notes.push_back(std::string("WATCHDOG: RLIMIT_RTTIME: ") + std::strerror(errno));
    } else {
      g_rttime_on = true;
    }
  }
  if (config.crash_handlers) {
    // An alternate stack for the main thread; RT tasks get one at attach.
    static char main_altstack[kAltStackBytes];
    stack_t ss{};
    ss.ss_sp = main_altstack;
    ss.ss_size = sizeof main_altstack;
    sigaltstack(&ss, nullptr);
    for (int sig : kCrashSignals) install(sig, &on_crash, SA_ONSTACK, &g_old_crash[sig]);
    g_crash_installed = true;
  }
  result.syscalls = g_sud_ok;
  result.faults = g_fault_ok;
  result.allocations = g_alloc_on && hooks;
  result.locks = g_locks_on && hooks;
  result.crash = g_crash_installed;
  result.rttime = g_rttime_on;
  {
    std::lock_guard lock(g_reporter_mutex);
    g_reporter_stop = false;
  }
  g_reporter = std::thread(&reporter_main);
  g_running.store(true, std::memory_order_release);
  return result;
}

void add_sink(std::shared_ptr<ReportSink> sink) {
  std::lock_guard lock(g_sinks_mutex);
  g_sinks.push_back(std::move(sink));
}

void stop() {
  if (!g_running.exchange(false, std::memory_order_acq_rel)) return;
  {
    std::lock_guard lock(g_reporter_mutex);
    g_reporter_stop = true;
  }
  g_reporter_cv.notify_all();
  if (g_reporter.joinable()) g_reporter.join();
  drain();
  if (try_lock_consumer(50 * kNsPerMs)) {  // the counts not yet written
    write_repeats(true);
    unlock_consumer();
  }
  if (g_written == 0 && g_report_fd >= 0) {
    // Nothing to report: leave no empty file behind, and no handler writing to it.
    if (g_crash_installed) {
      for (int sig : kCrashSignals) sigaction(sig, &g_old_crash[sig], nullptr);
      g_crash_installed = false;
    }
    ::close(g_report_fd);
    g_report_fd = -1;
    ::unlink(g_report_path);
    g_report_path[0] = '\0';
  }
}

bool running() noexcept { return g_running.load(std::memory_order_acquire); }

Counters counters() noexcept {
  Counters c;
  for (int k = 1; k < kReasonCount; ++k) {
    c.by_reason[k] = g_by_reason[k].load(std::memory_order_relaxed);
    c.reports += c.by_reason[k];
  }
  c.dropped = g_dropped.load(std::memory_order_relaxed);
  return c;
}

void attach_current_thread(const TaskInfo& info) {
  if (!running() || info.mode == Mode::kOff || t_slot != nullptr) return;
  TaskSlot* s = nullptr;
  for (auto& slot : g_tasks) {
    bool expected = false;
    if (slot.used.compare_exchange_strong(expected, true, std::memory_order_acq_rel)) {
      s = &slot;
      break;
    }
  }
  if (s == nullptr) return;  // more than kMaxTasks tasks: this one is not watched
  copy_text(s->task, sizeof s->task, info.task.c_str());
  copy_text(s->component, sizeof s->component, info.component.c_str());
  copy_text(s->label, sizeof s->label, info.label.c_str());
  s->address = info.address;
  s->mode = info.mode;
  s->tid = static_cast<int>(::syscall(SYS_gettid));
  s->cycle_reports = 0;
  s->selector = kAllow;
  s->sud = false;
  s->perf_fd = -1;
  if (g_crash_installed) {
    s->altstack = mmap(nullptr, kAltStackBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (s->altstack != MAP_FAILED) {
      stack_t ss{};
      ss.ss_sp = s->altstack;
      ss.ss_size = kAltStackBytes;
      sigaltstack(&ss, nullptr);
    } else {
      s->altstack = nullptr;
    }
  }
  if (g_sud_ok) {
    s->sud = prctl(PR_SET_SYSCALL_USER_DISPATCH, PR_SYS_DISPATCH_ON, g_sud_region, 16,
                   const_cast<char*>(&s->selector)) == 0;
  }
  if (g_fault_ok) s->perf_fd = open_page_fault_event();
  t_slot = s;
  const int64_t locked = vm_locked_kib();
  // ThreadSanitizer build: memory is never locked there (memory.h), nothing to report.
  if (locked == 0 && !kThreadSanitizer) record(Reason::kNoMlock, nullptr, 1, -1, nullptr, 0, locked);
}

void detach_current_thread() noexcept {
  TaskSlot* s = t_slot;
  if (s == nullptr) return;
  t_in_cycle = false;
  s->selector = kAllow;
  if (s->sud) prctl(PR_SET_SYSCALL_USER_DISPATCH, PR_SYS_DISPATCH_OFF, 0, 0, 0);
  if (s->perf_fd >= 0) ::close(s->perf_fd);
  if (s->altstack != nullptr) {
    stack_t ss{};
    ss.ss_flags = SS_DISABLE;
    sigaltstack(&ss, nullptr);
    munmap(s->altstack, kAltStackBytes);
  }
  t_slot = nullptr;
  // Free for the next task (reports carry copies of the names). Release: the next
  // owner's acquire CAS sees this thread done with it.
  s->used.store(false, std::memory_order_release);
}

void enter_cycle() noexcept {
  TaskSlot* s = t_slot;
  if (s == nullptr) return;
  s->cycle_reports = 0;
  s->xcpu_reported = false;
  s->framework_waits = 0;
  if (g_rusage) getrusage(RUSAGE_THREAD, &s->ru_start);
  t_in_cycle = true;
  std::atomic_signal_fence(std::memory_order_seq_cst);
  if (s->sud) s->selector = kBlock;  // last: the window opens here
}

Verdict leave_cycle() noexcept {
  TaskSlot* s = t_slot;
  if (s == nullptr) return {};
  s->selector = kAllow;  // first: the window closes here
  std::atomic_signal_fence(std::memory_order_seq_cst);
  t_in_cycle = false;
  if (g_rusage) {
    rusage now{};
    getrusage(RUSAGE_THREAD, &now);
    const uint64_t d[6] = {static_cast<uint64_t>(now.ru_minflt - s->ru_start.ru_minflt),
                           static_cast<uint64_t>(now.ru_majflt - s->ru_start.ru_majflt),
                           static_cast<uint64_t>(now.ru_nvcsw - s->ru_start.ru_nvcsw),
                           0,
                           0,
                           0};
    // A voluntary switch is expected when the cycle waited through the framework (an
    // RPC from on(), a contended PI lock); without such a wait something else blocked.
    // In a ThreadSanitizer build minor faults are its shadow memory's: not counted.
    const bool minor = d[0] != 0 && !kThreadSanitizer;
    if (minor || d[1] != 0 || (d[2] != 0 && s->framework_waits == 0)) {
      record(Reason::kRusage, nullptr, 1, -1, d, 0, 0);
    }
  }
  Verdict v;
  v.reports = s->cycle_reports;
  v.abort = s->mode == Mode::kAbort && v.reports > 0;
  if (v.abort && g_config.abort_action == AbortAction::kProcess) {
    // The report first (synchronously), then abort(): SIGABRT's crash report follows
    // and the default action dumps core.
    if (try_lock_consumer(kNsPerSec)) {
      drain_locked(false);
      unlock_consumer();
    }
    static constexpr char kMsg[] = "rack: mode-switch detection: abort mode with 'abort: process': aborting\n";
    write_all(STDERR_FILENO, kMsg, sizeof kMsg - 1);
    std::abort();
  }
  return v;
}

void note_overrun(uint64_t missed_periods, int64_t cycle_ns) noexcept {
  TaskSlot* s = t_slot;
  if (s == nullptr || g_config.watchdog_periods == 0 || missed_periods <= g_config.watchdog_periods) return;
  record(Reason::kWatchdog, nullptr, 1, 0, nullptr, 0, static_cast<int64_t>(missed_periods), cycle_ns);
}

TrustedScope::TrustedScope(bool may_block) noexcept : saved_(kAllow) {
  if (TaskSlot* s = t_slot) {
    if (may_block) s->framework_waits = s->framework_waits + 1;
    saved_ = s->selector;
    s->selector = kAllow;
    std::atomic_signal_fence(std::memory_order_seq_cst);
  }
}

TrustedScope::~TrustedScope() {
  if (TaskSlot* s = t_slot) {
    std::atomic_signal_fence(std::memory_order_seq_cst);
    s->selector = saved_;
  }
}

bool register_rt_device(int fd) noexcept {
  if (fd < 0 || fd >= kMaxFds) return false;
  const auto u = static_cast<uint64_t>(fd);
  // Relaxed: registration happens in init()/on(), long before the handler reads it
  // on another thread; the task start or the ON request orders them.
  g_rt_fds[u / 64].fetch_or(uint64_t{1} << (u % 64), std::memory_order_relaxed);
  return true;
}

void unregister_rt_device(int fd) noexcept {
  if (fd < 0 || fd >= kMaxFds) return;
  const auto u = static_cast<uint64_t>(fd);
  g_rt_fds[u / 64].fetch_and(~(uint64_t{1} << (u % 64)), std::memory_order_relaxed);
}

namespace detail {

__attribute__((noinline)) void on_heap_call(HeapCall call, std::size_t size) noexcept {
  if (!t_in_cycle || t_busy != 0 || !g_alloc_on) return;
  TaskSlot* s = t_slot;
  if (s == nullptr) return;
  // Frames above: capture, fill, record, on_heap_call, the interposer.
  record(Reason::kAlloc, nullptr, 2, static_cast<int64_t>(call), nullptr, 0, static_cast<int64_t>(size));
}

__attribute__((noinline)) int checked_mutex_lock(pthread_mutex_t* mutex, int (*real_lock)(pthread_mutex_t*)) noexcept {
  if (!t_in_cycle || t_busy != 0 || !g_locks_on || t_slot == nullptr) return real_lock(mutex);
  // glibc keeps the protocol in the mutex kind: PTHREAD_MUTEX_PRIO_INHERIT_NP (0x20)
  // and PTHREAD_MUTEX_PRIO_PROTECT_NP (0x40), nptl/pthreadP.h. Either bounds the wait.
  const int kind = mutex->__data.__kind;
  if ((kind & 0x60) == 0) {
    record(Reason::kPrioInv, nullptr, 2, 0, nullptr, reinterpret_cast<uintptr_t>(mutex), kind);
  }
  if (pthread_mutex_trylock(mutex) == 0) return 0;
  const int64_t t0 = monotonic_ns();
  const int rc = real_lock(mutex);
  const int64_t waited = monotonic_ns() - t0;
  if (waited > g_config.lock_wait_ns) {
    record(Reason::kPrioInv, nullptr, 2, 1, nullptr, reinterpret_cast<uintptr_t>(mutex), waited, g_config.lock_wait_ns);
  }
  return rc;
}

}  // namespace detail

}  // namespace rack::rt::modeswitch
