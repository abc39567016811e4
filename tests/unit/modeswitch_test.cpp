// Mode-switch detection in core/rt, in-process: each reason is recorded inside a
// cycle window with the right code, nothing is recorded outside it or for what the
// allow-list permits, and the calls that were trapped still return their results.
//
// Its own binary: it links the interposers (rack::rt_hooks) and starts the detector
// for the whole process (a gtest Environment), with the report file in a temporary
// directory. The process does not lock its memory, which is what NOMLOCK reports.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "rack/rt/clock.h"
#include "rack/rt/memory.h"
#include "rack/rt/modeswitch.h"
#include "rack/rt/pi_mutex.h"
#include "report_file.h"
#include "test_support.h"

namespace rack::rt::modeswitch {
namespace {

std::filesystem::path g_dir;
StartResult g_started;

class DetectorEnvironment : public ::testing::Environment {
 public:
  void SetUp() override {
    char tmpl[] = "/tmp/rack-modeswitch-test-XXXXXX";
    g_dir = mkdtemp(tmpl);
    Config c;
    c.crash_dir = g_dir.string();
    c.program = "modeswitch_test";
    c.to_stderr = false;
    c.lock_wait_ns = 5 * kNsPerMs;
    c.repeat_every_ns = 20 * kNsPerMs;  // identical reports' counts reach the file quickly
    g_started = start(c);
  }
  void TearDown() override {
    stop();
    std::filesystem::remove_all(g_dir);
  }
};
const auto* const g_env = ::testing::AddGlobalTestEnvironment(new DetectorEnvironment);

uint64_t count(Reason r) { return counters().by_reason[static_cast<int>(r)]; }

struct CycleResult {
  Verdict verdict;
  uint64_t before[kReasonCount] = {};
  uint64_t after[kReasonCount] = {};
  [[nodiscard]] uint64_t delta(Reason r) const { return after[static_cast<int>(r)] - before[static_cast<int>(r)]; }
  [[nodiscard]] uint64_t total() const {
    uint64_t t = 0;
    for (int k = 1; k < kReasonCount; ++k) t += after[k] - before[k];
    return t;
  }
};

// Runs `body` inside one cycle window on a fresh attached thread; `outside` runs on
// the same thread outside the window first.
CycleResult run_cycle(const std::function<void()>& body, Mode mode = Mode::kWarn,
                      const std::function<void()>& outside = {}) {
  CycleResult result;
  std::thread t([&] {
    prefault_stack(128 * 1024);  // as rt::Thread does: no stack faults inside the window
    TaskAttachment attach(TaskInfo{"test:cycle", "test", "Test(0/0)", 0, mode});
    if (outside) outside();
    // The attach may have recorded NOMLOCK (this process does not lock memory).
    const Counters c0 = counters();
    for (int k = 0; k < kReasonCount; ++k) result.before[k] = c0.by_reason[k];
    enter_cycle();
    body();
    result.verdict = leave_cycle();
    const Counters c1 = counters();
    for (int k = 0; k < kReasonCount; ++k) result.after[k] = c1.by_reason[k];
  });
  t.join();
  return result;
}

class ModeSwitchTest : public ::testing::Test {
 protected:
  test::Watchdog dog_;
};

TEST_F(ModeSwitchTest, EachMechanismIsOnOrSaysWhyNot) {
  // A kernel without Syscall User Dispatch (< 5.11) or perf sigtrap (< 5.13) leaves
  // that reason off, and start() must say so with a reason.
  std::string notes;
  for (const auto& n : g_started.notes) notes += n + "\n";
  EXPECT_TRUE(g_started.syscalls || notes.find("SYSCALL: skipped: ") != std::string::npos) << notes;
  EXPECT_TRUE(g_started.faults || notes.find("FAULT: skipped: ") != std::string::npos) << notes;
  EXPECT_TRUE(g_started.allocations || notes.find("ALLOC, PRIOINV: skipped: ") != std::string::npos) << notes;
  EXPECT_TRUE(g_started.locks || notes.find("ALLOC, PRIOINV: skipped: ") != std::string::npos) << notes;
  EXPECT_TRUE(g_started.crash) << notes;
  EXPECT_FALSE(g_started.report_path.empty()) << notes;
  EXPECT_NE(g_started.describe().find("reports to " + g_started.report_path), std::string::npos);
}

TEST_F(ModeSwitchTest, SyscallInCycleIsReportedAndStillWorks) {
  if (!g_started.syscalls) GTEST_SKIP() << "Syscall User Dispatch unavailable";
  const int fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ssize_t written = -2;
  const auto r = run_cycle([&] { written = ::write(fd, "hello", 5); });
  ::close(fd);
  EXPECT_EQ(written, 5) << "the trapped call is re-issued and its result returned";
  EXPECT_EQ(r.delta(Reason::kSyscall), 1u);
  EXPECT_EQ(r.total(), 1u);
  EXPECT_EQ(r.verdict.reports, 1u);
  EXPECT_FALSE(r.verdict.abort);
}

TEST_F(ModeSwitchTest, FailingSyscallKeepsItsErrno) {
  if (!g_started.syscalls) GTEST_SKIP() << "Syscall User Dispatch unavailable";
  int rc = 0, err = 0;
  const auto r = run_cycle([&] {
    rc = ::close(987654);  // not an open descriptor
    err = errno;
  });
  EXPECT_EQ(rc, -1);
  EXPECT_EQ(err, EBADF);
  EXPECT_EQ(r.delta(Reason::kSyscall), 1u);
}

TEST_F(ModeSwitchTest, AllowListAndFrameworkPrimitivesAreNotReported) {
  PiMutex m;
  PiCondVar cv;
  std::atomic<int> word{0};
  const auto r = run_cycle([&] {
    sleep_for(100 * kNsPerUs);  // clock_nanosleep via rt::
    timespec ts{0, 50'000};
    clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, nullptr);  // on the allow-list, called directly
    {
      PiLock lock(m);
      cv.notify_one();
    }
    {
      PiLock lock(m);
      (void)cv.wait_until(m, monotonic_ns() + 100 * kNsPerUs);  // times out
    }
    (void)monotonic_ns();  // vDSO
    (void)getpid();
    word.notify_one();  // futex (C++20 atomic wait/notify)
  });
  EXPECT_EQ(r.total(), 0u);
}

TEST_F(ModeSwitchTest, RegisteredRtDeviceIsAllowed) {
  if (!g_started.syscalls) GTEST_SKIP() << "Syscall User Dispatch unavailable";
  int fds[2];
  ASSERT_EQ(pipe2(fds, O_CLOEXEC | O_NONBLOCK), 0);
  ASSERT_TRUE(register_rt_device(fds[0]));
  ASSERT_TRUE(register_rt_device(fds[1]));
  char buf[4] = {};
  ssize_t w = 0, n = 0;
  const auto ok = run_cycle([&] {
    w = ::write(fds[1], "abc", 3);
    n = ::read(fds[0], buf, sizeof buf);
  });
  EXPECT_EQ(w, 3);
  EXPECT_EQ(n, 3);
  EXPECT_EQ(std::string(buf, 3), "abc");
  EXPECT_EQ(ok.total(), 0u);
  // poll: allowed when every descriptor in the array is registered; a bad array
  // pointer is the kernel's EFAULT, not a crash in the handler.
  int polled = -2, bad_poll = -2, bad_errno = 0;
  const auto p = run_cycle([&] {
    pollfd pfd[2] = {{fds[0], POLLIN, 0}, {fds[1], POLLOUT, 0}};
    polled = ::poll(pfd, 2, 0);
    pollfd* volatile unreadable = reinterpret_cast<pollfd*>(16);
    bad_poll = ::poll(unreadable, 1, 0);
    bad_errno = errno;
  });
  EXPECT_EQ(polled, 1) << "the pipe is writable";
  EXPECT_EQ(bad_poll, -1);
  EXPECT_EQ(bad_errno, EFAULT);
  EXPECT_EQ(p.delta(Reason::kSyscall), 1u) << "only the poll with the unreadable array";
  unregister_rt_device(fds[1]);
  const auto bad = run_cycle([&] { w = ::write(fds[1], "x", 1); });
  EXPECT_EQ(bad.delta(Reason::kSyscall), 1u) << "an unregistered descriptor is reported";
  unregister_rt_device(fds[0]);
  ::close(fds[0]);
  ::close(fds[1]);
}

void* volatile g_sink = nullptr;

TEST_F(ModeSwitchTest, AllocationAndReleaseAreReported) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  const auto r = run_cycle([&] {
    g_sink = std::malloc(64);
    std::free(g_sink);
  });
  EXPECT_EQ(r.delta(Reason::kAlloc), 2u) << "malloc and free";
  const auto n = run_cycle([&] {
    auto* p = new int[8];
    g_sink = p;
    delete[] p;
  });
  EXPECT_EQ(n.delta(Reason::kAlloc), 2u) << "operator new[] and delete[]";
}

TEST_F(ModeSwitchTest, NothingIsReportedOutsideTheWindow) {
  const int fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  const auto r = run_cycle([] {}, Mode::kWarn,
                           [&] {
                             g_sink = std::malloc(64);
                             std::free(g_sink);
                             (void)!::write(fd, "x", 1);
                             std::mutex m;
                             std::lock_guard lock(m);
                           });
  ::close(fd);
  EXPECT_EQ(r.total(), 0u);
}

TEST_F(ModeSwitchTest, NonPiMutexIsPriorityInversion) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  std::mutex plain;
  PiMutex pi;
  const auto r = run_cycle([&] {
    { std::lock_guard lock(plain); }
    { PiLock lock(pi); }
  });
  EXPECT_EQ(r.delta(Reason::kPrioInv), 1u) << "the std::mutex, not the PI mutex";
}

TEST_F(ModeSwitchTest, LongWaitOnPiMutexIsPriorityInversion) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  PiMutex pi;
  std::atomic<bool> held{false};
  std::thread holder([&] {
    PiLock lock(pi);
    held.store(true);
    sleep_for(30 * kNsPerMs);  // longer than the 5 ms threshold of this test
  });
  while (!held.load()) sleep_for(100 * kNsPerUs);
  const auto r = run_cycle([&] { PiLock lock(pi); });
  holder.join();
  EXPECT_EQ(r.delta(Reason::kPrioInv), 1u);
}

TEST_F(ModeSwitchTest, PageFaultIsReported) {
  if (!g_started.faults) GTEST_SKIP() << "perf sigtrap unavailable";
  const long page = sysconf(_SC_PAGESIZE);
  auto* area = static_cast<char*>(
      mmap(nullptr, static_cast<std::size_t>(page) * 4, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0));
  ASSERT_NE(area, MAP_FAILED);
  const auto r = run_cycle([&] { *static_cast<volatile char*>(area + page) = 1; });
  EXPECT_GE(r.delta(Reason::kFault), 1u);
  EXPECT_EQ(r.delta(Reason::kSyscall), 0u);
  munmap(area, static_cast<std::size_t>(page) * 4);
}

TEST_F(ModeSwitchTest, AbortModeFailsTheCycleWarnModeDoesNot) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  const auto warn = run_cycle(
      [] {
        g_sink = std::malloc(8);
        std::free(g_sink);
      },
      Mode::kWarn);
  EXPECT_FALSE(warn.verdict.abort);
  const auto abort = run_cycle(
      [] {
        g_sink = std::malloc(8);
        std::free(g_sink);
      },
      Mode::kAbort);
  EXPECT_TRUE(abort.verdict.abort);
  const auto clean = run_cycle([] {}, Mode::kAbort);
  EXPECT_FALSE(clean.verdict.abort);
  const auto off = run_cycle(
      [] {
        g_sink = std::malloc(8);
        std::free(g_sink);
      },
      Mode::kOff);
  EXPECT_EQ(off.total(), 0u);
}

TEST_F(ModeSwitchTest, NoMlockIsReportedAtTaskStart) {
  if (kThreadSanitizer) GTEST_SKIP() << "NOMLOCK is not reported in a ThreadSanitizer build (memory is never locked)";
  // This test process never called mlockall.
  const uint64_t before = count(Reason::kNoMlock);
  std::thread t([] { TaskAttachment attach(TaskInfo{"test:nomlock", "test", "Test(0/0)", 0, Mode::kWarn}); });
  t.join();
  EXPECT_EQ(count(Reason::kNoMlock), before + 1);
}

TEST_F(ModeSwitchTest, OverrunBeyondTheWatchdogIsReported) {
  const uint64_t before = count(Reason::kWatchdog);
  std::thread t([] {
    TaskAttachment attach(TaskInfo{"test:overrun", "test", "Test(0/0)", 0, Mode::kWarn});
    note_overrun(3, 1000);   // below the default 20 periods
    note_overrun(25, 1000);  // above
  });
  t.join();
  EXPECT_EQ(count(Reason::kWatchdog), before + 1);
}

TEST_F(ModeSwitchTest, ReportFileHoldsModulesAndCompleteReports) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  if (g_started.report_path.empty()) GTEST_SKIP() << "no report file";
  (void)run_cycle([] {
    g_sink = std::malloc(8);
    std::free(g_sink);
  });
  // The reporter writes within its 20 ms poll; bounded wait.
  std::string text;
  for (int i = 0; i < 200; ++i) {
    std::ifstream in(g_started.report_path);
    std::stringstream ss;
    ss << in.rdbuf();
    text = ss.str();
    if (text.find("reason=ALLOC") != std::string::npos) break;
    sleep_for(10 * kNsPerMs);
  }
  EXPECT_EQ(text.rfind("RACK-MODESWITCH-REPORT 1 ", 0), 0u);
  EXPECT_NE(text.find("\nmodule 0 base=0x"), std::string::npos);
  EXPECT_NE(text.find("build_id="), std::string::npos);
  const auto at = text.find("reason=ALLOC mode=warn task=test:cycle component=test label=Test(0/0)");
  ASSERT_NE(at, std::string::npos) << text;
  EXPECT_NE(text.find("detail malloc(", at), std::string::npos) << text;
  EXPECT_NE(text.find("frame 0 0x", at), std::string::npos);
  if (::testing::Test::HasFailure() || std::getenv("RACK_SHOW_REPORT") != nullptr) std::fputs(text.c_str(), stderr);
  EXPECT_NE(text.find("\nend ", at), std::string::npos);
}

// The interface the GDOS issue will plug into: every report reaches every sink, on
// the reporter thread, with its fields and the same text as the file.
class CollectingSink : public ReportSink {
 public:
  void publish(const ReportView& r, std::string_view text) override {
    std::lock_guard lock(mutex_);
    if (r.task != "test:sink") return;
    reasons_.push_back(r.reason);
    details_.emplace_back(r.detail);
    texts_.emplace_back(text);
    frames_ = r.frames.size();
    component_ = std::string(r.component);
    label_ = std::string(r.label);
  }
  std::mutex mutex_;
  std::vector<Reason> reasons_;
  std::vector<std::string> details_, texts_;
  std::size_t frames_ = 0;
  std::string component_, label_;
};

TEST_F(ModeSwitchTest, SinksReceiveEveryReport) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  auto sink = std::make_shared<CollectingSink>();
  add_sink(sink);
  std::thread t([] {
    TaskAttachment attach(TaskInfo{"test:sink", "sinky", "Sink(0/3)", 0, Mode::kWarn});
    enter_cycle();
    g_sink = std::malloc(24);
    std::free(g_sink);
    (void)leave_cycle();
  });
  t.join();
  bool got = false;
  for (int i = 0; i < 300 && !got; ++i) {
    {
      std::lock_guard lock(sink->mutex_);
      got = sink->reasons_.size() >= 2;
    }
    if (!got) sleep_for(10 * kNsPerMs);
  }
  std::lock_guard lock(sink->mutex_);
  ASSERT_GE(sink->reasons_.size(), 2u);
  EXPECT_EQ(sink->component_, "sinky");
  EXPECT_EQ(sink->label_, "Sink(0/3)");
  EXPECT_GT(sink->frames_, 0u);
  bool malloc_seen = false;
  for (std::size_t k = 0; k < sink->reasons_.size(); ++k) {
    if (sink->reasons_[k] == Reason::kAlloc && sink->details_[k] == "malloc(24 bytes) in a real-time cycle") {
      malloc_seen = true;
      EXPECT_NE(sink->texts_[k].find("reason=ALLOC mode=warn task=test:sink"), std::string::npos) << sink->texts_[k];
    }
  }
  EXPECT_TRUE(malloc_seen);
}

TEST_F(ModeSwitchTest, AFullRingDropsAndCountsAndRecovers) {
  if (!g_started.allocations) GTEST_SKIP() << "no interposers in this build (sanitizer)";
  const Counters before = counters();
  // Far more reports in one cycle than the ring holds (128): the excess is dropped
  // and counted, the task is never blocked.
  const auto r = run_cycle([] {
    for (int k = 0; k < 400; ++k) {
      g_sink = std::malloc(16);
      std::free(g_sink);
    }
  });
  EXPECT_EQ(r.delta(Reason::kAlloc), 800u) << "every one is counted";
  EXPECT_GT(counters().dropped, before.dropped) << "the ring overflowed";
  // The reporter drains it; later reports get through again.
  sleep_for(200 * kNsPerMs);
  const uint64_t dropped = counters().dropped;
  const auto again = run_cycle([] {
    g_sink = std::malloc(8);
    std::free(g_sink);
  });
  EXPECT_EQ(again.delta(Reason::kAlloc), 2u);
  EXPECT_EQ(counters().dropped, dropped);
}

// Several RT threads report at once (the ring's producers race on their CAS) while
// the reporter writes: every report that was not dropped reaches the file exactly
// once, complete or counted as a repeat of an identical one (read back with
// rack-backtrace's own parser).
TEST_F(ModeSwitchTest, ConcurrentProducersLoseNothingButWhatIsCountedAsDropped) {
  if (!g_started.allocations || g_started.report_path.empty()) GTEST_SKIP() << "no interposers or no report file";
  auto count_in_file = [] {
    std::ifstream in(g_started.report_path);
    const auto file = backtrace::parse_report_file(in, g_started.report_path);
    EXPECT_TRUE(file.errors.empty()) << file.errors.front();
    uint64_t n = 0;
    for (const auto& r : file.reports) {
      if (r.field("task").rfind("test:mp", 0) == 0) n += 1 + r.repeats;  // any reason: FAULT and NOMLOCK share the ring
    }
    return n;
  };
  sleep_for(100 * kNsPerMs);  // what earlier tests (or repetitions) reported is written
  const uint64_t in_file_before = count_in_file();
  const Counters before = counters();
  constexpr int kThreads = 4, kCycles = 150;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([t] {
      TaskAttachment attach(TaskInfo{"test:mp" + std::to_string(t), "mp", "Mp(0/0)", 0, Mode::kWarn});
      for (int k = 0; k < kCycles; ++k) {
        enter_cycle();
        g_sink = std::malloc(32);
        std::free(g_sink);
        (void)leave_cycle();
        if (k % 10 == 0) sleep_for(200 * kNsPerUs);
      }
    });
  }
  for (auto& th : threads) th.join();
  const Counters after = counters();
  // This process does not lock its memory: besides the ALLOC reports, the threads
  // also record NOMLOCK and page faults; all of them compete for the ring.
  const uint64_t recorded = after.reports - before.reports;
  const uint64_t dropped = after.dropped - before.dropped;
  EXPECT_EQ(after.by_reason[static_cast<int>(Reason::kAlloc)] - before.by_reason[static_cast<int>(Reason::kAlloc)],
            uint64_t{kThreads} * kCycles * 2);
  uint64_t in_file = 0;
  for (int i = 0; i < 300; ++i) {
    in_file = count_in_file() - in_file_before;
    if (in_file >= recorded - dropped) break;
    sleep_for(10 * kNsPerMs);
  }
  EXPECT_EQ(in_file, recorded - dropped) << "recorded " << recorded << ", dropped " << dropped;
}

// The same report many times (one site, every cycle): the file holds it once in full
// and `repeat` lines with the count, so it stays small; the counts add up.
TEST_F(ModeSwitchTest, IdenticalReportsAreCountedNotWrittenAgain) {
  if (!g_started.allocations || g_started.report_path.empty()) GTEST_SKIP() << "no interposers or no report file";
  auto read = [] {
    std::ifstream in(g_started.report_path);
    return backtrace::parse_report_file(in, g_started.report_path);
  };
  sleep_for(100 * kNsPerMs);
  const auto size_before = std::filesystem::file_size(g_started.report_path);
  const Counters before = counters();
  constexpr int kCycles = 2000;
  std::thread t([] {
    TaskAttachment attach(TaskInfo{"test:repeat", "rep", "Rep(0/0)", 0, Mode::kWarn});
    for (int k = 0; k < kCycles; ++k) {
      enter_cycle();
      g_sink = std::malloc(40);  // the same two call sites each cycle
      std::free(g_sink);
      (void)leave_cycle();
      if (k % 50 == 0) sleep_for(1 * kNsPerMs);  // let the reporter keep up with the ring
    }
  });
  t.join();
  const Counters after = counters();
  const uint64_t recorded = after.by_reason[static_cast<int>(Reason::kAlloc)] -
                            before.by_reason[static_cast<int>(Reason::kAlloc)];
  ASSERT_EQ(recorded, uint64_t{kCycles} * 2);
  const uint64_t dropped = after.dropped - before.dropped;
  uint64_t in_file = 0, written = 0;
  for (int i = 0; i < 300; ++i) {
    in_file = written = 0;
    for (const auto& r : read().reports) {
      if (r.field("task") != "test:repeat" || r.field("reason") != "ALLOC") continue;
      ++written;
      in_file += 1 + r.repeats;
    }
    if (in_file + dropped >= recorded) break;
    sleep_for(10 * kNsPerMs);
  }
  EXPECT_EQ(written, 2u) << "malloc and free: one report each in full";
  // Every report is in the file (in full or counted) unless the ring dropped it (the
  // drop count also holds this thread's other reasons: NOMLOCK, FAULT).
  EXPECT_LE(in_file, recorded);
  EXPECT_GE(in_file + dropped, recorded) << "dropped " << dropped;
  // 4000 reports in full would be well over 1 MB; written once plus repeat lines, a few KB.
  EXPECT_LT(std::filesystem::file_size(g_started.report_path) - size_before, 64u * 1024);
}

TEST_F(ModeSwitchTest, SyscallNamesComeFromTheKernelHeaders) {
  EXPECT_STREQ(syscall_name(1), "write");
  EXPECT_EQ(syscall_number("futex"), 202);
  EXPECT_EQ(syscall_name(100000), nullptr);
  EXPECT_EQ(parse_reason("PRIOINV"), Reason::kPrioInv);
  EXPECT_EQ(parse_mode("abort"), Mode::kAbort);
  EXPECT_FALSE(parse_mode("loud").has_value());
}

}  // namespace
}  // namespace rack::rt::modeswitch
