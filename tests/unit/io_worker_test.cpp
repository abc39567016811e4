// Components never make threads (issue 22 item 2, STYLE.md 3): blocking device I/O
// runs in executor-owned I/O workers (Component::add_io_worker), and everything a
// component says goes through GDOS. Checked here two ways: the sources under
// components/ make no thread and print nothing to stderr/stdout, and the executor
// runs a declared worker after init(), places it on the housekeeping CPUs, names it in
// its thread listing and stops and joins it before cleanup(). A compute worker
// (Component::add_compute_worker, MCL's likelihood) runs where its data task runs, and
// without a serving thread (a stepped executor starts none) its jobs run on the
// poster's thread.
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>

#include "rack/core/compute_worker.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/demo.h"
#include "rack/rt/clock.h"
#include "rack/rt/thread.h"
#include "test_support.h"

namespace rack {
namespace {

using test::HostUnderTest;
using test::Watchdog;

// ---- the sources ------------------------------------------------------------

// Files under components/ that may make threads or print, each with the reason. None:
// MCL's likelihood thread is an executor-owned compute worker now.
const std::set<std::string> kAllowed = {};

// What a line of code (its comment cut off) must not do, and why.
struct Rule {
  std::regex pattern;
  const char* why;
};

std::vector<std::string> offences_under(const std::filesystem::path& root, const std::vector<Rule>& rules) {
  std::vector<std::string> out;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
    if (!entry.is_regular_file()) continue;
    const std::string ext = entry.path().extension().string();
    if (ext != ".cpp" && ext != ".h" && ext != ".hpp" && ext != ".cc") continue;
    const std::string rel = std::filesystem::relative(entry.path(), RACK_SOURCE_DIR).string();
    // Device simulators (tests' and benches' stand-ins for hardware), not components.
    if (rel.rfind("components/sims/", 0) == 0 || kAllowed.count(rel) != 0) continue;
    std::ifstream in(entry.path());
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      if (const auto c = line.find("//"); c != std::string::npos) line.resize(c);
      for (const auto& r : rules) {
        if (std::regex_search(line, r.pattern)) out.push_back(rel + ":" + std::to_string(n) + ": " + r.why);
      }
    }
  }
  return out;
}

TEST(ComponentSourceTest, NoComponentMakesAThreadOrPrints) {
  const std::filesystem::path root = std::filesystem::path(RACK_SOURCE_DIR) / "components";
  ASSERT_TRUE(std::filesystem::is_directory(root)) << root;
  const std::vector<Rule> rules = {
      {std::regex(R"(std::j?thread\b|pthread_create)"),
       "makes a thread (declare an I/O worker, Component::add_io_worker, or a compute worker, "
       "Component::add_compute_worker)"},
      {std::regex(R"(\bstderr\b|\bstdout\b|std::cerr|std::cout|std::clog|(^|[^a-z_])printf\s*\(|(^|[^a-z_])puts\s*\()"),
       "prints (log through GDOS: log_info, log_warning, log_error)"},
  };
  const auto found = offences_under(root, rules);
  std::string all;
  for (const auto& f : found) all += f + "\n";
  EXPECT_TRUE(found.empty()) << all;
}

// The rules find what they are meant to find (a check that cannot fail proves nothing).
TEST(ComponentSourceTest, TheRulesCatchThreadsAndPrints) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("rack-io-worker-rules-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "bad.cpp")
      << "void f() {\n  std::thread t([] {});\n  std::fprintf(stderr, \"x\");\n"
         "  printf(\"y\");\n  // std::thread in a comment is fine\n  snprintf(b, 1, \"z\");\n}\n";
  const std::vector<Rule> rules = {
      {std::regex(R"(std::j?thread\b|pthread_create)"), "thread"},
      {std::regex(R"(\bstderr\b|(^|[^a-z_])printf\s*\()"), "print"},
  };
  const auto found = offences_under(dir, rules);
  std::filesystem::remove_all(dir);
  ASSERT_EQ(found.size(), 3U);
  EXPECT_NE(found[0].find(":2: thread"), std::string::npos) << found[0];
  EXPECT_NE(found[1].find(":3: print"), std::string::npos) << found[1];
  EXPECT_NE(found[2].find(":4: print"), std::string::npos) << found[2];
}

// ---- the executor's I/O workers ------------------------------------------------

// Declares one I/O worker in init() that runs until stopped, and records the order
// of events; `fail_init` declares the worker and then throws.
class IoWorkerComponent final : public Component {
 public:
  static inline std::atomic<int> running{0};               // bodies running now
  static inline std::atomic<int> ran{0};                   // bodies that ran
  static inline std::atomic<bool> body_at_cleanup{false};  // a body still ran when cleanup() came
  static inline std::atomic<int> turns{0};                 // sleeps the bodies have ended
  explicit IoWorkerComponent(bool fail_init) : fail_init_(fail_init) {}

 protected:
  void init() override {
    add_io_worker(
        "test-io",
        [this] {
          running.fetch_add(1);
          ran.fetch_add(1);
          while (!stop_.load(std::memory_order_acquire)) {
            rt::sleep_for(2 * rt::kNsPerMs);
            turns.fetch_add(1);
          }
          running.fetch_sub(1);
        },
        [this] { stop_.store(true, std::memory_order_release); });
    if (fail_init_) throw std::runtime_error("init fails after declaring a worker");
  }
  void cleanup() override { body_at_cleanup = body_at_cleanup || running.load() != 0; }

 private:
  bool fail_init_;
  std::atomic<bool> stop_{false};
};

void register_io_classes(ComponentRegistry& r) {
  r.add({"IoWorkerOk", tims::classes::kFirstUser, "test: declares an I/O worker",
         [] { return std::make_unique<IoWorkerComponent>(false); }});
  r.add({"IoWorkerFailingInit", static_cast<uint8_t>(tims::classes::kFirstUser + 1),
         "test: declares an I/O worker, then init() throws", [] { return std::make_unique<IoWorkerComponent>(true); }});
}

// This process's CPU affinity, put back when the guard goes: a host with `cpus:`
// partitioning moves the threads of the process it runs in, the test's own too.
class AffinityGuard {
 public:
  AffinityGuard() {
    CPU_ZERO(&before_);
    ok_ = sched_getaffinity(0, sizeof before_, &before_) == 0;
  }
  ~AffinityGuard() {
    if (ok_) (void)sched_setaffinity(0, sizeof before_, &before_);
  }
  AffinityGuard(const AffinityGuard&) = delete;
  AffinityGuard& operator=(const AffinityGuard&) = delete;
  // CPUs 0 and 1 are both in it (what a `cpus: {rt: 1, housekeeping: 0}` host needs).
  [[nodiscard]] bool has_cpus_0_and_1() const { return ok_ && CPU_ISSET(0, &before_) && CPU_ISSET(1, &before_); }

 private:
  cpu_set_t before_;
  bool ok_ = false;
};

std::string cpus_of_thread_named(const std::string& wanted, pid_t& tid) {
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(entry.path() / "comm");
    std::string name;
    std::getline(comm, name);
    if (name != wanted) continue;
    tid = static_cast<pid_t>(std::stoi(entry.path().filename().string()));
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(tid, sizeof set, &set) != 0) return "?";
    std::vector<int> cpus;
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(static_cast<std::size_t>(c), &set)) cpus.push_back(c);
    }
    return rt::cpu_list_string(cpus);
  }
  tid = 0;
  return "";
}

TEST(IoWorkerTest, RunsAfterInitOnTheHousekeepingCpusAndEndsBeforeCleanup) {
  Watchdog watchdog;
  const AffinityGuard affinity;
  if (!affinity.has_cpus_0_and_1()) GTEST_SKIP() << "needs CPUs 0 and 1 in this process's affinity";
  IoWorkerComponent::running = 0;
  IoWorkerComponent::ran = 0;
  IoWorkerComponent::body_at_cleanup = false;
  {
    HostUnderTest host(R"(system: 0
lcm: false
cpus: {rt: 1, housekeeping: 0}
components:
  - name: io
    class: IoWorkerOk
    instance: 1
  - name: broken
    class: IoWorkerFailingInit
    instance: 1
)",
                       register_io_classes);
    ASSERT_TRUE(test::eventually([] { return IoWorkerComponent::running.load() == 1; }));
    pid_t tid = 0;
    EXPECT_EQ(cpus_of_thread_named("test-io", tid), "0") << "the worker runs on the housekeeping CPU only";
    ASSERT_NE(tid, 0);
    const std::string report = host.executor().thread_report();
    const auto at = report.find("test-io");
    ASSERT_NE(at, std::string::npos) << report;
    const auto eol = report.find('\n', at);
    EXPECT_NE(report.substr(at, eol - at).find("I/O worker, not RT"), std::string::npos) << report;
    host.executor().stop();
    EXPECT_EQ(IoWorkerComponent::running.load(), 0) << "stop() stopped and joined the worker";
    EXPECT_FALSE(IoWorkerComponent::body_at_cleanup.load()) << "the worker ended before cleanup()";
  }
  EXPECT_EQ(IoWorkerComponent::ran.load(), 1) << "the worker of the component whose init() failed never ran";
}

// A stepped executor (rack/core/stepper.h) keeps the I/O workers' real threads: they
// run on the kernel's clock and never move the virtual one. Neither start-up's wait for
// the worker's thread id nor the worker's own rt::sleep_for() is time passing for the
// stepped components (a real thread that sleeps in a loop moved it at full speed).
TEST(IoWorkerTest, ASteppedExecutorsWorkerLeavesTheVirtualClockAlone) {
  Watchdog watchdog;
  IoWorkerComponent::running = 0;
  IoWorkerComponent::turns = 0;
  {
    HostUnderTest host(R"(system: 0
lcm: false
components:
  - {name: io, class: IoWorkerOk, instance: 1}
)",
                       register_io_classes, false, test::Stepping::kStepped);
    Stepper& s = host.stepper();
    const int64_t t0 = rt::VirtualClock::kDefaultStartNs;
    EXPECT_EQ(s.now_ns(), t0) << "start-up's wait for the worker's thread moved the virtual clock";
    ASSERT_TRUE(test::eventually([] { return IoWorkerComponent::turns.load() >= 5; }));
    EXPECT_EQ(s.now_ns(), t0) << IoWorkerComponent::turns.load()
                              << " turns of the worker's rt::sleep_for(2 ms) moved the virtual clock";
    EXPECT_EQ(s.run_for(100 * rt::kNsPerMs), 0u);  // no data task
    EXPECT_EQ(s.now_ns(), t0 + 100 * rt::kNsPerMs) << "only the stepper moves it";
    host.executor().stop();
    EXPECT_EQ(IoWorkerComponent::running.load(), 0) << "stop() stopped and joined the worker";
  }
}

// ---- compute workers -----------------------------------------------------------

TEST(ComputeWorkerTest, WithoutAServingThreadTheJobRunsOnThePoster) {
  ComputeWorker worker;
  EXPECT_TRUE(worker.wait()) << "nothing posted: nothing to wait for";
  pid_t ran_on = 0;
  auto job = [&ran_on] { ran_on = static_cast<pid_t>(::syscall(SYS_gettid)); };
  worker.post(job);
  EXPECT_TRUE(worker.wait());
  EXPECT_EQ(ran_on, static_cast<pid_t>(::syscall(SYS_gettid)));
  EXPECT_EQ(worker.jobs_inline(), 1u);
  auto throws = [] { throw std::runtime_error("job fails"); };
  worker.post(throws);
  EXPECT_FALSE(worker.wait()) << "a job that threw is reported, not passed on";
  worker.stop();  // stopped before any thread served it: still runs jobs on the poster
  worker.post(job);
  EXPECT_TRUE(worker.wait());
  EXPECT_EQ(worker.jobs_inline(), 3u);
}

TEST(ComputeWorkerTest, AServingThreadRunsEachJobAndStopsAfterIt) {
  Watchdog watchdog;
  ComputeWorker worker;
  std::thread server([&worker] { worker.serve(); });
  ASSERT_TRUE(test::eventually([&] { return worker.serving(); }));
  std::atomic<pid_t> ran_on{0};
  std::atomic<int> runs{0};
  auto job = [&] {
    ran_on = static_cast<pid_t>(::syscall(SYS_gettid));
    rt::sleep_for(rt::kNsPerMs);
    runs.fetch_add(1);
  };
  for (int i = 0; i < 20; ++i) {
    worker.post(job);
    ASSERT_TRUE(worker.wait());
    ASSERT_EQ(runs.load(), i + 1) << "wait() returned before the job did";
  }
  EXPECT_NE(ran_on.load(), static_cast<pid_t>(::syscall(SYS_gettid)));
  worker.post(job);  // posted before stop(): still runs
  worker.stop();
  EXPECT_TRUE(worker.wait());
  server.join();
  EXPECT_EQ(runs.load(), 21);
  EXPECT_FALSE(worker.serving());
  EXPECT_EQ(worker.jobs_served(), 21u);
  EXPECT_EQ(worker.jobs_inline(), 0u);
}

// A data component that declares a compute worker in init() and hands it a job every
// cycle; records the thread each job ran on and whether the worker was still served
// when cleanup() came.
class ComputeWorkerComponent final : public DataComponent<interfaces::GeneratorData> {
 public:
  static inline std::atomic<pid_t> job_tid{0};
  static inline std::atomic<pid_t> loop_tid{0};
  static inline std::atomic<int> jobs{0};
  static inline std::atomic<bool> served_at_cleanup{false};
  ComputeWorkerComponent() : DataComponent(DataTaskMode::kPeriodic) {}

 protected:
  void init() override { worker_ = &add_compute_worker("calc"); }
  HookResult loop() override {
    loop_tid = static_cast<pid_t>(::syscall(SYS_gettid));
    auto job = [] {
      job_tid = static_cast<pid_t>(::syscall(SYS_gettid));
      jobs.fetch_add(1);
    };
    worker_->post(job);
    return worker_->wait() ? HookResult::kOk : HookResult::kError;
  }
  void cleanup() override { served_at_cleanup = worker_->serving(); }

 private:
  ComputeWorker* worker_ = nullptr;
};

// One ComputeWorkerComponent 'cw', switched on at start, its data task not RT (priority
// 0) every 5 ms; `head` goes before `components:`.
std::string compute_worker_yaml(const std::string& head = "") {
  return "system: 0\nlcm: false\n" + head + R"(components:
  - name: cw
    class: ComputeWorkerTest
    instance: 1
    autostart: true
    data_task: {priority: 0, period_ms: 5}
)";
}

TEST(ComputeWorkerTest, TheExecutorRunsItWhereTheDataTaskRunsAndJoinsItBeforeCleanup) {
  Watchdog watchdog;
  const AffinityGuard affinity;
  if (!affinity.has_cpus_0_and_1()) GTEST_SKIP() << "needs CPUs 0 and 1 in this process's affinity";
  ComputeWorkerComponent::jobs = 0;
  ComputeWorkerComponent::served_at_cleanup = true;
  {
    // A non-RT data task (priority 0): with partitioning, on the housekeeping CPU.
    HostUnderTest host(compute_worker_yaml("cpus: {rt: 1, housekeeping: 0}\n"),
                       test::one_class<ComputeWorkerComponent>("ComputeWorkerTest", "test: declares a compute worker"));
    ASSERT_TRUE(test::eventually([] { return ComputeWorkerComponent::jobs.load() >= 5; })) << host.log();
    pid_t tid = 0;
    EXPECT_EQ(cpus_of_thread_named("cw:calc", tid), "0") << "the data task's CPUs: the housekeeping CPU";
    ASSERT_NE(tid, 0);
    EXPECT_EQ(ComputeWorkerComponent::job_tid.load(), tid) << "the jobs ran on the worker's thread";
    EXPECT_NE(ComputeWorkerComponent::loop_tid.load(), tid);
    EXPECT_EQ(sched_getscheduler(tid), SCHED_OTHER) << "the data task's priority 0: normal scheduling";
    const std::string report = host.executor().thread_report();
    const auto at = report.find("cw:calc");
    ASSERT_NE(at, std::string::npos) << report;
    EXPECT_NE(report.substr(at, report.find('\n', at) - at).find("compute worker, not RT"), std::string::npos)
        << report;
    host.executor().stop();
    EXPECT_FALSE(ComputeWorkerComponent::served_at_cleanup.load()) << "the worker ended before cleanup()";
    EXPECT_EQ(cpus_of_thread_named("cw:calc", tid), "") << "joined";
  }
}

// A stepped executor (rack/core/stepper.h) starts no thread for the worker: the job
// runs inside the step that posts it, on the stepping thread, and start-up waits for
// no worker thread (which would move the virtual clock).
TEST(ComputeWorkerTest, ASteppedExecutorRunsEachJobInsideTheStepThatPostsIt) {
  Watchdog watchdog;
  ComputeWorkerComponent::jobs = 0;
  ComputeWorkerComponent::job_tid = 0;
  ComputeWorkerComponent::served_at_cleanup = true;
  {
    HostUnderTest host(compute_worker_yaml(),
                       test::one_class<ComputeWorkerComponent>("ComputeWorkerTest", "test: declares a compute worker"),
                       false, test::Stepping::kStepped);
    Stepper& s = host.stepper();
    EXPECT_EQ(s.now_ns(), rt::VirtualClock::kDefaultStartNs) << "start-up moved the virtual clock";
    ASSERT_EQ(host.status(host.address_of("cw")), tims::msg::kEnabled) << host.log();
    s.advance(5 * rt::kNsPerMs);
    ASSERT_TRUE(s.step("cw"));
    EXPECT_EQ(ComputeWorkerComponent::jobs.load(), 1) << "the job ran inside the step";
    const auto self = static_cast<pid_t>(::syscall(SYS_gettid));
    EXPECT_EQ(ComputeWorkerComponent::job_tid.load(), self) << "on the stepping thread";
    EXPECT_EQ(ComputeWorkerComponent::loop_tid.load(), self);
    EXPECT_EQ(s.run_for(20 * rt::kNsPerMs), 4u);
    EXPECT_EQ(ComputeWorkerComponent::jobs.load(), 5) << "one job a cycle, each done when its step returned";
    const std::string report = host.executor().thread_report();
    EXPECT_EQ(report.find("cw:calc"), std::string::npos) << "no worker thread\n" << report;
    host.executor().stop();
    EXPECT_FALSE(ComputeWorkerComponent::served_at_cleanup.load());
  }
}

}  // namespace
}  // namespace rack
