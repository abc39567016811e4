// Mode-switch detection end to end: the real rackd runs the ModeSwitchDemo component,
// the real rackctl triggers each reason with a class command, and the real
// rack-backtrace must symbolize each report to the line of the demo that caused it
// (marked `DEMO-LINE: <deed>` in components/modeswitch_demo/modeswitch_demo.cpp).
// Also: our own components under a periodic load produce no report at all, a crash
// writes a complete report and the process still dies with the original signal, and
// rack-backtrace says clearly when a report is truncated or a binary does not match.
//
// Behaviour only, no timings: waits are bounded generously.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kBacktrace = RACK_BACKTRACE_PATH;
const std::string kDemoSource = std::string(RACK_SOURCE_DIR) + "/components/modeswitch_demo/modeswitch_demo.cpp";

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

int count_of(const std::string& text, const std::string& part) {
  int n = 0;
  for (auto at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

// Line numbers of the `DEMO-LINE: X` markers.
std::map<std::string, int> demo_lines() {
  std::map<std::string, int> out;
  std::ifstream in(kDemoSource);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    const auto at = line.find("DEMO-LINE: ");
    if (at != std::string::npos) out[line.substr(at + 11)] = n;
  }
  return out;
}

class ModeSwitchIntegrationTest : public ::testing::Test {
 protected:
  ModeSwitchIntegrationTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  std::string crash_dir() const { return (dir_.path() / "crash").string(); }

  std::unique_ptr<Process> start_rackd(const std::string& host_text) {
    const auto file = dir_.write("host.yaml", host_text);
    auto p = std::make_unique<Process>(std::vector<std::string>{kRackd, file.string(), "--lcm", bus_.url(),
                                                                "--crash-dir", crash_dir()},
                                       dir_.path(), "rackd");
    if (!p->wait_for_stderr("rackd: running", 30s)) {
      ADD_FAILURE() << "rackd did not start:\n" << p->err();
      return nullptr;
    }
    return p;
  }

  RunResult ctl(std::vector<std::string> args) {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url(), "--discover-ms", "3000"});
    return run(args, 30s);
  }

  RunResult backtrace(std::vector<std::string> args) {
    args.insert(args.begin(), kBacktrace);
    return run(args, 60s);
  }

  std::vector<std::string> report_files() const {
    std::vector<std::string> out;
    if (!std::filesystem::exists(crash_dir())) return out;
    for (const auto& e : std::filesystem::directory_iterator(crash_dir())) out.push_back(e.path().string());
    return out;
  }

  // Waits until rackd's stderr shows `n` reports of `reason`.
  bool wait_reports(Process& p, const std::string& reason, int n) {
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    while (std::chrono::steady_clock::now() < deadline) {
      if (count_of(p.err(), "reason=" + reason + " ") >= n) return true;
      std::this_thread::sleep_for(50ms);
    }
    return false;
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
};

constexpr const char* kDemoHost = R"(host: it-modeswitch
system: 0
heap_prefault_mib: 16
modeswitch:
  rttime_ms: 100
components:
  - name: demo
    class: ModeSwitchDemo
    instance: 0
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 40, period_ms: 10}
)";

TEST_F(ModeSwitchIntegrationTest, DemoHostFileIsValid) {
  const RunResult r = run({kRackd, "--check", std::string(RACK_CONFIGS_DIR) + "/modeswitch_demo.yaml"}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "valid (3 component(s))")) << r.describe();
}

TEST_F(ModeSwitchIntegrationTest, EachReasonIsReportedAndSymbolizesToTheDemoLine) {
  const auto lines = demo_lines();
  ASSERT_EQ(lines.size(), 10u) << "markers in " << kDemoSource;
  auto rackd = start_rackd(kDemoHost);
  ASSERT_TRUE(rackd);
  if (contains(rackd->err(), "skipped: ")) {
    GTEST_SKIP() << "this kernel lacks a mechanism (unit test EachMechanismIsOnOrSaysWhyNot covers the message):\n"
                 << rackd->err();
  }
  ASSERT_TRUE(contains(rackd->err(), "SYSCALL on, FAULT on, ALLOC on, PRIOINV on, crash reports on, RLIMIT_RTTIME on"))
      << rackd->err();

  struct Case {
    const char* cmd;
    const char* reason;
    const char* marker;  // the demo line the report must symbolize to
    const char* task;
  };
  const Case cases[] = {
      {"21", "SYSCALL", "SYSCALL", "demo:cmd"},       {"22", "FAULT", "FAULT", "demo:cmd"},
      {"23", "ALLOC", "ALLOC", "demo:cmd"},           {"24", "PRIOINV", "PRIOINV", "demo:cmd"},
      {"30", "SYSCALL", "LOOP_SYSCALL", "demo:data"},
  };
  int syscalls = 0;
  for (const auto& c : cases) {
    const RunResult r = ctl({"send", "demo", c.cmd});
    ASSERT_EQ(r.exit_code, 0) << r.describe();
    const int want = std::string(c.reason) == "SYSCALL" ? ++syscalls : 1;
    EXPECT_TRUE(wait_reports(*rackd, c.reason, want)) << c.cmd << "\n" << rackd->err();
  }
  // WATCHDOG twice: RLIMIT_RTTIME in the command task, a 30-period overrun in loop().
  ASSERT_EQ(ctl({"send", "demo", "25", "--i64", "400"}).exit_code, 0);
  EXPECT_TRUE(wait_reports(*rackd, "WATCHDOG", 1)) << rackd->err();
  ASSERT_EQ(ctl({"send", "demo", "26"}).exit_code, 0);
  EXPECT_TRUE(wait_reports(*rackd, "WATCHDOG", 2)) << rackd->err();
  // A registered RT device: allowed, no report.
  ASSERT_EQ(ctl({"send", "demo", "27"}).exit_code, 0);

  rackd->signal(SIGTERM);
  ASSERT_EQ(rackd->wait_exit(30s), 0) << rackd->err();
  const std::string err = rackd->err();
  EXPECT_EQ(count_of(err, "reason=SYSCALL "), 2) << err;  // the device write added none
  EXPECT_EQ(count_of(err, "reason=ALLOC "), 2) << err;    // new[] and delete[]
  EXPECT_TRUE(contains(err, "detail cycle overran by ")) << err;
  EXPECT_TRUE(contains(err, "detail RLIMIT_RTTIME: ran more than 100000 us")) << err;
  EXPECT_TRUE(contains(err, "mode switch(es) reported")) << err;
  const auto files = report_files();
  ASSERT_EQ(files.size(), 1u);

  for (const auto& c : cases) {
    const RunResult r = backtrace({"--reason", c.reason, "--task", c.task, files[0]});
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    const std::string where = "modeswitch_demo.cpp:" + std::to_string(lines.at(c.marker));
    EXPECT_TRUE(contains(r.out, where)) << c.reason << " must symbolize to " << where << "\n" << r.out;
    EXPECT_TRUE(contains(r.out, "[" + std::string(c.reason) + "] task " + std::string(c.task) +
                                    ", component demo ModeSwitchDemo(0/0)"))
        << r.out;
  }
  const RunResult spin = backtrace({"--reason", "WATCHDOG", "--task", "demo:cmd", files[0]});
  EXPECT_TRUE(contains(spin.out, "modeswitch_demo.cpp:" + std::to_string(lines.at("SPIN")))) << spin.out;
  const RunResult syscall = backtrace({"--reason", "SYSCALL", "--task", "demo:cmd", files[0]});
  EXPECT_TRUE(contains(syscall.out, "write(0x")) << syscall.out;
  EXPECT_TRUE(contains(syscall.out, "is not a registered RT device")) << syscall.out;

  // Filters by function and file, and the summary groups identical backtraces.
  const RunResult by_function = backtrace({"--function", "do_prioinv", files[0]});
  EXPECT_EQ(count_of(by_function.out, "[PRIOINV]"), 1) << by_function.out;
  EXPECT_EQ(count_of(by_function.out, "[SYSCALL]"), 0) << by_function.out;
  const RunResult by_file = backtrace({"--file", "nowhere_such_file.cpp", files[0]});
  EXPECT_EQ(by_file.out, "") << by_file.out;
  const RunResult summary = backtrace({"--summary", files[0]});
  EXPECT_TRUE(contains(summary.out, "1 x [FAULT] task demo:cmd")) << summary.out;
  EXPECT_TRUE(contains(summary.out, "report(s) in ")) << summary.out;
}

// The same mode switch many times (issue 21): the report file holds it once in full
// and `repeat` lines with counts, so a fault that repeats cannot fill a disk; the
// counts add up to every report, and rack-backtrace counts them.
TEST_F(ModeSwitchIntegrationTest, IdenticalReportsAreAggregatedAndTheToolsCountThem) {
  auto rackd = start_rackd(R"(host: it-modeswitch-repeat
system: 0
heap_prefault_mib: 16
modeswitch:
  repeat_ms: 5000
components:
  - name: demo
    class: ModeSwitchDemo
    instance: 0
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 40, period_ms: 10}
)");
  ASSERT_TRUE(rackd);
  if (!contains(rackd->err(), "SYSCALL on")) GTEST_SKIP() << "no SYSCALL detection here:\n" << rackd->err();
  constexpr int kSends = 20;
  for (int i = 0; i < kSends; ++i) {
    const RunResult r = ctl({"send", "demo", "21"});  // write() in a command handler, the same line each time
    ASSERT_EQ(r.exit_code, 0) << r.describe();
  }
  rackd->signal(SIGTERM);
  ASSERT_EQ(rackd->wait_exit(30s), 0) << rackd->err();
  const auto files = report_files();
  ASSERT_EQ(files.size(), 1u);
  const std::string text = read_file(files[0]);
  EXPECT_EQ(count_of(text, "reason=SYSCALL "), 1) << "written once in full\n" << text;
  uint64_t repeated = 0;
  int repeat_lines = 0;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("repeat ", 0) != 0) continue;
    ++repeat_lines;
    const auto at = line.find(" count=");
    ASSERT_NE(at, std::string::npos) << line;
    repeated += std::stoull(line.substr(at + 7));
  }
  EXPECT_EQ(repeated, uint64_t{kSends - 1}) << text;
  EXPECT_GE(repeat_lines, 1);
  EXPECT_LE(repeat_lines, 4) << "at most one line per 5 s while it repeats, and one at exit\n" << text;
  EXPECT_TRUE(contains(rackd->err(), "repeated ")) << rackd->err();
  const RunResult summary = backtrace({"--summary", files[0]});
  EXPECT_EQ(summary.exit_code, 0) << summary.describe();
  EXPECT_TRUE(contains(summary.out, std::to_string(kSends) + " x [SYSCALL] task demo:cmd")) << summary.out;
  const RunResult full = backtrace({"--reason", "SYSCALL", files[0]});
  EXPECT_TRUE(contains(full.out, "and " + std::to_string(kSends - 1) + " identical report(s) after it")) << full.out;
}

TEST_F(ModeSwitchIntegrationTest, AbortModePutsTheComponentInError) {
  auto rackd = start_rackd(R"(host: it-modeswitch-abort
system: 0
heap_prefault_mib: 16
components:
  - name: demo
    class: ModeSwitchDemo
    instance: 0
    autostart: true
    retry_ms: 600000
    command_task: {priority: 30, modeswitch: abort}
    data_task: {priority: 40, period_ms: 10, modeswitch: warn}
)");
  ASSERT_TRUE(rackd);
  if (contains(rackd->err(), "SYSCALL: skipped: ")) GTEST_SKIP() << "no Syscall User Dispatch:\n" << rackd->err();
  ASSERT_EQ(ctl({"send", "demo", "30"}).exit_code, 0);  // loop() in warn mode: reported, stays on
  ASSERT_TRUE(wait_reports(*rackd, "SYSCALL", 1)) << rackd->err();
  RunResult st = ctl({"status", "demo"});
  EXPECT_TRUE(contains(st.out, "ENABLED")) << st.describe();
  ASSERT_EQ(ctl({"send", "demo", "21"}).exit_code, 0);  // command task in abort mode
  ASSERT_TRUE(wait_reports(*rackd, "SYSCALL", 2)) << rackd->err();
  EXPECT_TRUE(contains(rackd->err(), "mode=abort task=demo:cmd")) << rackd->err();
  st = ctl({"status", "demo"});
  EXPECT_TRUE(contains(st.out, "ERROR")) << st.describe();
  rackd->signal(SIGTERM);
  EXPECT_EQ(rackd->wait_exit(30s), 0) << rackd->err();
}

// Our own components and the executor: a periodic load with listeners, RPCs from
// rackctl, and the demo component idle: not one report.
TEST_F(ModeSwitchIntegrationTest, OurComponentsRunALoadWithoutReports) {
  auto rackd = start_rackd(R"(host: it-modeswitch-quiet
system: 0
heap_prefault_mib: 16
modeswitch:
  rusage: true
components:
  - name: generator
    class: Generator
    instance: 0
    data_task: {priority: 60, period_ms: 1}
  - name: monitor
    class: Monitor
    instance: 0
    autostart: true
    data_task: {priority: 50}
    params: {source: generator, source_period_ms: 0, silence_ms: 1000}
  - name: monitor2
    class: Monitor
    instance: 1
    autostart: true
    data_task: {priority: 50}
    params: {source: generator, source_period_ms: 10, silence_ms: 1000}
  - name: probe
    class: Probe
    instance: 0
    autostart: true
    data_task: {priority: 45, period_ms: 2}
  - name: demo
    class: ModeSwitchDemo
    instance: 0
    autostart: true
    data_task: {priority: 40, period_ms: 5}
)");
  ASSERT_TRUE(rackd);
  if (contains(rackd->err(), "skipped: ")) GTEST_SKIP() << "this kernel lacks a mechanism:\n" << rackd->err();
  ASSERT_TRUE(contains(rackd->err(), "SYSCALL on, FAULT on, ALLOC on, PRIOINV on")) << rackd->err();
  // Work for the command tasks while the data tasks run: status, data, parameters,
  // a short subscription, OFF/ON cycles of the consumer.
  for (int round = 0; round < 3; ++round) {
    EXPECT_EQ(ctl({"status", "generator"}).exit_code, 0);
    EXPECT_EQ(ctl({"get-data", "monitor"}).exit_code, 0);
    EXPECT_EQ(ctl({"params", "generator"}).exit_code, 0);
    EXPECT_EQ(ctl({"set-param", "generator", "amplitude", "3.5"}).exit_code, 0);
    EXPECT_EQ(ctl({"set-param", "probe", "label", "round" + std::to_string(round)}).exit_code, 0);  // string
    EXPECT_EQ(ctl({"status", "probe"}).exit_code, 0);
    EXPECT_EQ(ctl({"watch", "generator", "--count", "5"}).exit_code, 0);
    EXPECT_EQ(ctl({"off", "monitor2"}).exit_code, 0);
    EXPECT_EQ(ctl({"on", "monitor2"}).exit_code, 0);
    EXPECT_EQ(ctl({"send", "demo", "27"}).exit_code, 0);  // RT device I/O is allowed
  }
  std::this_thread::sleep_for(1s);
  rackd->signal(SIGTERM);
  ASSERT_EQ(rackd->wait_exit(30s), 0) << rackd->err();
  const std::string err = rackd->err();
  EXPECT_FALSE(contains(err, "MODE SWITCH")) << err;
  EXPECT_FALSE(contains(err, "mode switch(es) reported")) << err;
  EXPECT_TRUE(report_files().empty()) << "an empty report file is removed at exit";
}

TEST_F(ModeSwitchIntegrationTest, AbortProcessWritesTheReportThenDumpsCore) {
  auto rackd = start_rackd(R"(host: it-modeswitch-abort-process
system: 0
heap_prefault_mib: 16
modeswitch:
  mode: abort
  abort: process
components:
  - name: demo
    class: ModeSwitchDemo
    instance: 0
    autostart: true
    data_task: {period_ms: 10}
)");
  ASSERT_TRUE(rackd);
  if (contains(rackd->err(), "SYSCALL: skipped: ")) GTEST_SKIP() << "no Syscall User Dispatch:\n" << rackd->err();
  (void)ctl({"send", "demo", "21", "--timeout", "1000"});  // never answered: rackd aborts
  const auto code = rackd->wait_exit(30s);
  ASSERT_TRUE(code.has_value()) << rackd->err();
  EXPECT_EQ(rackd->term_signal(), SIGABRT) << rackd->err();
  const std::string err = rackd->err();
  const auto syscall = err.find("reason=SYSCALL mode=abort task=demo:cmd");
  const auto crash = err.find("reason=CRASH");
  ASSERT_NE(syscall, std::string::npos) << err;
  ASSERT_NE(crash, std::string::npos) << err;
  EXPECT_LT(syscall, crash) << "the mode switch is reported before the abort";
  const auto files = report_files();
  ASSERT_EQ(files.size(), 1u);
  const RunResult r = backtrace({"--reason", "SYSCALL", files[0]});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "modeswitch_demo.cpp:" + std::to_string(demo_lines().at("SYSCALL")))) << r.out;
}

TEST_F(ModeSwitchIntegrationTest, RusageSeesASleepThatBypassesTheFramework) {
  auto rackd = start_rackd(R"(host: it-modeswitch-rusage
system: 0
heap_prefault_mib: 16
modeswitch:
  rusage: true
components:
  - name: demo
    class: ModeSwitchDemo
    instance: 0
    autostart: true
    data_task: {period_ms: 10}
)");
  ASSERT_TRUE(rackd);
  ASSERT_EQ(ctl({"send", "demo", "31"}).exit_code, 0);
  ASSERT_TRUE(wait_reports(*rackd, "RUSAGE", 1)) << rackd->err();
  rackd->signal(SIGTERM);
  ASSERT_EQ(rackd->wait_exit(30s), 0) << rackd->err();
  const std::string err = rackd->err();
  EXPECT_EQ(count_of(err, "reason=RUSAGE mode=warn task=demo:cmd"), 1) << err;
  EXPECT_TRUE(contains(err, "voluntary context switches +")) << err;
  EXPECT_EQ(count_of(err, "reason=SYSCALL"), 0) << "clock_nanosleep itself is allowed\n" << err;
}

// A class from a plug-in: the report symbolizes into the shared library through its
// own load address and build id.
TEST_F(ModeSwitchIntegrationTest, PluginCodeSymbolizesToItsOwnSource) {
  const std::string plugin = RACK_TEST_PLUGIN_PATH;
  auto rackd = start_rackd("host: it-modeswitch-plugin\nsystem: 0\nheap_prefault_mib: 16\nplugins: [" + plugin +
                           "]\ncomponents:\n  - name: plug\n    class: PluginDemo\n    instance: 0\n"
                           "    autostart: true\n");
  ASSERT_TRUE(rackd);
  if (contains(rackd->err(), "SYSCALL: skipped: ")) GTEST_SKIP() << "no Syscall User Dispatch:\n" << rackd->err();
  ASSERT_EQ(ctl({"send", "plug", "21"}).exit_code, 0);
  ASSERT_TRUE(wait_reports(*rackd, "SYSCALL", 1)) << rackd->err();
  rackd->signal(SIGTERM);
  ASSERT_EQ(rackd->wait_exit(30s), 0) << rackd->err();
  const auto files = report_files();
  ASSERT_EQ(files.size(), 1u);
  EXPECT_TRUE(contains(read_file(files[0]), "path=" + plugin)) << "the plug-in's module line";
  int line = 0;
  std::ifstream in(std::string(RACK_SOURCE_DIR) + "/tests/integration/plugin/modeswitch_plugin.cpp");
  std::string text;
  for (int n = 1; std::getline(in, text); ++n) {
    if (contains(text, "PLUGIN-LINE: SYSCALL")) line = n;
  }
  ASSERT_GT(line, 0);
  const RunResult r = backtrace({"--reason", "SYSCALL", files[0]});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "modeswitch_plugin.cpp:" + std::to_string(line) + "  (librack_test_plugin.so+0x"))
      << r.out;
}

class CrashTest : public ModeSwitchIntegrationTest, public ::testing::WithParamInterface<const char*> {};

TEST_P(CrashTest, ReportIsCompleteAndTheProcessDiesWithTheSignal) {
  const bool segv = std::string(GetParam()) == "CRASH";
  const auto lines = demo_lines();
  auto rackd = start_rackd(kDemoHost);
  ASSERT_TRUE(rackd);
  (void)ctl({"send", "demo", segv ? "28" : "29", "--timeout", "1000"});  // never answered
  const auto code = rackd->wait_exit(30s);
  ASSERT_TRUE(code.has_value()) << rackd->err();
  EXPECT_EQ(*code, -1) << "killed by a signal, not exited";
  EXPECT_EQ(rackd->term_signal(), segv ? SIGSEGV : SIGABRT) << rackd->err();
  EXPECT_TRUE(contains(rackd->err(), segv ? "detail SIGSEGV (si_code 1) at address 0x0" : "detail SIGABRT"))
      << rackd->err();
  const auto files = report_files();
  ASSERT_EQ(files.size(), 1u);
  const RunResult r = backtrace({"--reason", "CRASH", files[0]});
  EXPECT_EQ(r.exit_code, 0) << "complete: no truncation\n" << r.describe();
  EXPECT_TRUE(contains(r.out, "[CRASH] task demo:cmd, component demo ModeSwitchDemo(0/0)")) << r.out;
  EXPECT_TRUE(contains(r.out, "modeswitch_demo.cpp:" + std::to_string(lines.at(GetParam())))) << r.out;
}
INSTANTIATE_TEST_SUITE_P(Signals, CrashTest, ::testing::Values("CRASH", "ABORT"));

// rack-backtrace on damaged input: clear errors, exit 1, the rest still printed.
TEST_F(ModeSwitchIntegrationTest, BacktraceToolNamesTruncatedReportsAndMismatchedBinaries) {
  auto rackd = start_rackd(kDemoHost);
  ASSERT_TRUE(rackd);
  if (contains(rackd->err(), "SYSCALL: skipped: ")) GTEST_SKIP() << "no Syscall User Dispatch:\n" << rackd->err();
  ASSERT_EQ(ctl({"send", "demo", "21"}).exit_code, 0);
  ASSERT_EQ(ctl({"send", "demo", "23"}).exit_code, 0);
  ASSERT_TRUE(wait_reports(*rackd, "ALLOC", 2)) << rackd->err();
  rackd->signal(SIGTERM);
  ASSERT_EQ(rackd->wait_exit(30s), 0);
  const auto files = report_files();
  ASSERT_EQ(files.size(), 1u);
  const std::string text = read_file(files[0]);

  // Cut inside the last report.
  const auto cut = text.rfind("frame 2 ");
  ASSERT_NE(cut, std::string::npos);
  const auto truncated = dir_.write("truncated.report", text.substr(0, cut));
  RunResult r = backtrace({truncated.string()});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "is truncated")) << r.err;
  EXPECT_TRUE(contains(r.out, "[SYSCALL]")) << "the complete reports are still shown\n" << r.out;

  // Another binary than the one that ran: the build id of module 0 changed.
  std::string other = text;
  const auto at = other.find("build_id=");
  ASSERT_NE(at, std::string::npos);
  other.replace(at + 9, 4, other.compare(at + 9, 4, "0000") == 0 ? "1111" : "0000");
  const auto mismatched = dir_.write("mismatch.report", other);
  r = backtrace({mismatched.string()});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "does not match the report: build id")) << r.err;

  // Not a report at all; stdin; --help.
  r = backtrace({dir_.write("junk.txt", "hello\n").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_TRUE(contains(r.err, "not a RACK mode-switch report")) << r.err;
  r = run({"/bin/sh", "-c", kBacktrace + " --reason ALLOC < " + files[0]}, 60s);  // standard input
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_EQ(count_of(r.out, "[ALLOC]"), 2) << r.out;
  EXPECT_TRUE(contains(r.out, "<stdin>:")) << r.out;
  r = run({kRackctl, "--lcm", bus_.url(), "send", "demo", "5"}, 30s);  // a generic command number
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "class command number 21..127")) << r.err;
  r = backtrace({"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_TRUE(contains(r.out, "usage: rack-backtrace")) << r.out;
  r = backtrace({"--reason", "LOUD", files[0]});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
}

}  // namespace
}  // namespace rack::test
