// Page faults of RT tasks after their start-up (rack/rt/page_faults.h): the counter
// counts (a probe thread that touches fresh pages after its mark), and a simple
// periodic component in an executor with rackd's memory policy takes none. And the
// executor keeps its own non-RT threads off the CPUs its RT tasks are pinned to.
#include <sys/mman.h>
#include <unistd.h>

#include <sched.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "rack/rt/memory.h"
#include "rack/core/wire_tasks.h"
#include "rack/rt/page_faults.h"
#include "rack/rt/task_sched.h"
#include "test_support.h"

namespace rack {
namespace {

using test::Watchdog;

TEST(PageFaultsTest, CountsTheFaultsAThreadTakesAfterItsStartUpMark) {
  Watchdog watchdog;
  constexpr std::size_t kPages = 64;
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  void* mem = mmap(nullptr, kPages * page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(mem, MAP_FAILED);
  // Not resident, whatever the process's memory policy (MCL_FUTURE populates new
  // mappings): the probe's first touch of each page is a minor fault.
  (void)munlock(mem, kPages * page);
  ASSERT_EQ(madvise(mem, kPages * page, MADV_DONTNEED), 0);

  rt::TaskFaults faults;
  EXPECT_FALSE(faults.sample().measured);  // not started yet
  std::atomic<int> phase{0};
  std::thread probe([&] {
    faults.mark_started();
    phase.store(1);
    while (phase.load() != 2) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    auto* bytes = static_cast<volatile char*>(mem);
    for (std::size_t i = 0; i < kPages; ++i) bytes[i * page] = 1;  // the deliberate faults
    phase.store(3);
    while (phase.load() != 4) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  });
  while (phase.load() != 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const rt::FaultCount before = faults.sample();  // from this (other) thread, as the executor does
  ASSERT_TRUE(before.measured);
  EXPECT_EQ(before.major, 0u);
  phase.store(2);
  while (phase.load() != 3) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const rt::FaultCount after = faults.sample();
  phase.store(4);
  probe.join();
  ASSERT_TRUE(after.measured);
  EXPECT_GE(after.minor - before.minor, kPages);
  EXPECT_EQ(faults.last().minor, after.minor);  // last() is what the sample left
  munmap(mem, kPages * page);
}

TEST(PageFaultsTest, ReadingAThreadThatDoesNotExistIsNotAMeasurement) {
  EXPECT_FALSE(rt::read_thread_faults(0).measured);
  EXPECT_TRUE(rt::read_thread_faults(static_cast<pid_t>(gettid())).measured);
}

// A 1 kHz Generator in an executor with rackd's memory policy (memory locked before
// the tasks start, heap pre-faulted, stacks pre-faulted): once running, neither its
// data task nor its command task (answering GET_STATS) takes a page fault.
TEST(PageFaultsTest, PeriodicComponentTakesNoPageFaultAfterStartUp) {
  Watchdog watchdog;
  const auto mem = rt::apply_memory_policy(64u << 20);
  if (mem.skipped_for_sanitizer) GTEST_SKIP() << mem.describe();
  if (!mem.locked) GTEST_SKIP() << "mlockall refused (needs root or RLIMIT_MEMLOCK): " << mem.describe();
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 60, period_ms: 1, ring: 100}
)");
  const tims::Address gen = host.address_of("gen");
  Component* c = host.executor().find("gen");
  ASSERT_NE(c, nullptr);
  ASSERT_TRUE(host.wait_status(gen, tims::msg::kEnabled));
  // Run for a while, the command task answering requests meanwhile.
  wire::StatsReply st;
  ASSERT_TRUE(test::eventually([&] {
    const auto r = host.call(gen, tims::msg::kGetStats);
    if (r.status != tims::CallStatus::kOk || r.body.size() != sizeof st) return false;
    std::memcpy(&st, r.body.data(), sizeof st);
    return st.data.cycles >= 400;
  }));
  c->sample_faults();
  const rt::FaultCount cmd = c->command_task_faults().last();
  const rt::FaultCount data = c->data_task_faults().last();
  ASSERT_TRUE(cmd.measured);
  ASSERT_TRUE(data.measured);
  EXPECT_EQ(data.minor, 0u) << "data task faulted after start-up";
  EXPECT_EQ(data.major, 0u);
  EXPECT_EQ(cmd.minor, 0u) << "command task faulted after start-up";
  EXPECT_EQ(cmd.major, 0u);
  // GET_STATS carries the same figures (rackctl status).
  const auto r = host.call(gen, tims::msg::kGetStats);
  ASSERT_EQ(r.body.size(), sizeof st);
  std::memcpy(&st, r.body.data(), sizeof st);
  EXPECT_EQ(st.faults_measured, 3);
  EXPECT_EQ(st.data_minor_faults, 0u);
  EXPECT_EQ(st.command_minor_faults, 0u);
  // And rackd's status lines show them.
  EXPECT_NE(host.executor().status_report().find("page faults after start-up: command task 0 minor 0 major (RT), "
                                                 "data task 0 minor 0 major (RT)"),
            std::string::npos)
      << host.executor().status_report();
}

}  // namespace
}  // namespace rack

namespace rack {
namespace {

// A component that declares a non-RT I/O worker in init(), as drivers do for device
// I/O (components make no threads: the executor runs the worker).
class ThreadInInit final : public Component {
 protected:
  void init() override {
    add_io_worker(
        "test-io",
        [this] {
          while (!quit_.load()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
        },
        [this] { quit_ = true; });
  }

 private:
  std::atomic<bool> quit_{false};
};

// The id of this process's thread named `name`, 0 when there is none.
pid_t thread_named(const std::string& wanted) {
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream comm(entry.path() / "comm");
    std::string name;
    std::getline(comm, name);
    if (name == wanted) return static_cast<pid_t>(std::stoi(entry.path().filename().string()));
  }
  return 0;
}

// The CPUs thread `tid` of this process may run on (sched_getaffinity).
cpu_set_t affinity_of(pid_t tid) {
  cpu_set_t set;
  CPU_ZERO(&set);
  EXPECT_EQ(sched_getaffinity(tid, sizeof set, &set), 0);
  return set;
}

// The executor's own non-RT threads (here: the GDOS thread and a component's I/O
// worker, declared in init()) stay off a CPU that an RT
// task is pinned to; the thread that started the executor gets its full set back.
TEST(HousekeepingAffinityTest, GdosAndInitThreadsStayOffTheCpuOfAPinnedRtTask) {
  Watchdog watchdog;
  const cpu_set_t before = affinity_of(0);
  if (CPU_COUNT(&before) < 2) GTEST_SKIP() << "needs 2 CPUs in this process's affinity";
  int pinned = -1;
  for (int cpu = CPU_SETSIZE - 1; cpu >= 0 && pinned < 0; --cpu) {
    if (CPU_ISSET(static_cast<std::size_t>(cpu), &before)) pinned = cpu;  // the highest allowed CPU
  }
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    command_task: {priority: 30, cpu: )" +
                               std::to_string(pinned) + R"(}
    data_task: {priority: 60, cpu: )" +
                               std::to_string(pinned) + R"(, period_ms: 10}
  - name: io
    class: ThreadInInit
)",
                           test::one_class<ThreadInInit>("ThreadInInit", "test: an I/O worker from init()"));
  const cpu_set_t after = affinity_of(0);
  EXPECT_TRUE(CPU_EQUAL(&before, &after)) << "the starting thread's affinity was not restored";
  // Find the GDOS thread by name among this process's threads.
  pid_t gdos = 0;
  ASSERT_TRUE(test::eventually([&] {
    for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
      std::ifstream comm(entry.path() / "comm");
      std::string name;
      std::getline(comm, name);
      if (name == "rackd:gdos") {
        gdos = static_cast<pid_t>(std::stoi(entry.path().filename().string()));
        return true;
      }
    }
    return false;
  }));
  const cpu_set_t g = affinity_of(gdos);
  EXPECT_FALSE(CPU_ISSET(static_cast<std::size_t>(pinned), &g))
      << "GDOS thread may run on CPU " << pinned << ", where RT tasks are pinned";
  EXPECT_GE(CPU_COUNT(&g), 1);
  // The I/O worker the component declared in init() (as a driver's device I/O).
  pid_t io = 0;
  ASSERT_TRUE(test::eventually([&] {
    io = thread_named("test-io");
    return io != 0;
  }));
  const cpu_set_t t = affinity_of(io);
  EXPECT_FALSE(CPU_ISSET(static_cast<std::size_t>(pinned), &t))
      << "init()'s thread may run on CPU " << pinned << ", where RT tasks are pinned";
}

// How a thread runs, as the kernel says (rack/rt/task_sched.h): this test's thread
// runs under normal scheduling somewhere it may; a thread that does not exist is no
// reading; TaskSched keeps the last reading.
TEST(TaskSchedTest, ReadsPolicyPriorityAndCpusOfAThread) {
  const pid_t self = static_cast<pid_t>(::gettid());
  const rt::SchedInfo s = rt::read_thread_sched(self);
  ASSERT_TRUE(s.measured);
  const int policy = sched_getscheduler(0);
  EXPECT_EQ(s.policy, policy);
  EXPECT_EQ(s.priority, policy == SCHED_FIFO || policy == SCHED_RR ? s.priority : 0);
  const cpu_set_t mine = affinity_of(0);
  for (std::size_t c = 0; c < rt::SchedInfo::kCpuWords * 64; ++c) {
    EXPECT_EQ(((s.affinity[c / 64] >> (c % 64)) & 1u) != 0, CPU_ISSET(c, &mine) != 0) << "CPU " << c;
  }
  EXPECT_TRUE(CPU_ISSET(static_cast<std::size_t>(s.last_cpu), &mine)) << s.last_cpu;
  EXPECT_GE(s.online_cpus, 1);
  EXPECT_FALSE(rt::read_thread_sched(0).measured);
  EXPECT_FALSE(rt::read_thread_sched(0x7ffffff0).measured);
  rt::TaskSched t;
  EXPECT_FALSE(t.last().measured);
  t.sample(0x7ffffff0);
  EXPECT_FALSE(t.last().measured) << "a thread that does not exist";
  t.sample(self);
  EXPECT_TRUE(t.last().measured);
  EXPECT_EQ(t.last().affinity, s.affinity);
}

// GET_TASKS (wire::TasksReply): a running generator says how its tasks run: the host
// file's priorities and CPU, the kernel's policy, priority and CPUs (its data task
// pinned), its timer period and the interval its loop() runs at (tolerant: only that
// it is measured and near 10 ms, not how near).
TEST(TaskSchedTest, GetTasksSaysHowTheTasksRunTolerant) {
  Watchdog watchdog;
  const cpu_set_t before = affinity_of(0);
  int pinned = -1;
  for (int cpu = CPU_SETSIZE - 1; cpu >= 0 && pinned < 0; --cpu) {
    if (CPU_ISSET(static_cast<std::size_t>(cpu), &before)) pinned = cpu;  // the highest allowed CPU
  }
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 60, cpu: )" +
                           std::to_string(pinned) + R"(, period_ms: 10}
)");
  const tims::Address gen = host.address_of("gen");
  wire::TasksReply r;
  ASSERT_TRUE(test::eventually(
      [&] {
        const auto reply = host.call(gen, tims::msg::kGetTasks);
        if (reply.type != tims::msg::kTasks) return false;
        const char* bad = wire::decode_tasks(std::as_bytes(std::span(reply.body.data(), reply.body.size())), true, r);
        EXPECT_EQ(bad, nullptr) << bad;
        return bad == nullptr && r.measured[0] == 1 && r.measured[1] == 1 && r.measured_period_ns[1] > 0;
      },
      std::chrono::seconds(10)))
      << "no measured TASKS reply";
  EXPECT_EQ(r.version, wire::kTasksVersion);
  EXPECT_EQ(r.data_task, 1u);
  EXPECT_EQ(r.task_count, 2u);
  EXPECT_EQ(r.network_count, 0u) << "lcm: false";
  EXPECT_EQ(r.configured_priority[0], 30);
  EXPECT_EQ(r.configured_priority[1], 60);
  EXPECT_EQ(r.configured_cpu[0], -1);
  EXPECT_EQ(r.configured_cpu[1], pinned);
  // SCHED_FIFO as asked, or normal scheduling where RT is refused (the fallback).
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_TRUE(r.policy[i] == 1 || r.policy[i] == 0) << int{r.policy[i]};
    EXPECT_EQ(r.priority[i], r.policy[i] == 1 ? r.configured_priority[i] : 0);
  }
  for (std::size_t w = 0; w < wire::kTaskCpuWords; ++w) {
    EXPECT_EQ(r.affinity[wire::kTaskCpuWords + w],
              pinned / 64 == static_cast<int>(w) ? uint64_t{1} << (pinned % 64) : 0u)
        << "the data task is pinned to CPU " << pinned;
  }
  EXPECT_EQ(r.last_cpu[1], pinned);
  EXPECT_EQ(r.period_ns[0], 0);
  EXPECT_EQ(r.period_ns[1], 10 * rt::kNsPerMs);
  EXPECT_GT(r.measured_period_ns[1], 5 * rt::kNsPerMs);
  EXPECT_LT(r.measured_period_ns[1], 50 * rt::kNsPerMs);
  const uint64_t x = 1;
  EXPECT_EQ(host.call_with(gen, tims::msg::kGetTasks, x).type, tims::msg::kError) << "GET_TASKS takes no body";
}

}  // namespace
}  // namespace rack

namespace rack {
namespace {

// The partitioning tests need CPUs 0 and 1; partition_threads() moves this thread too,
// so its affinity is given back after each test. This binary does not link rackd's
// pthread_create (rack::rt_hooks, rack/rt/thread_birth.h): its threads are born where
// their creator runs, as glibc's own helper threads are in rackd, which is what the
// sweep is the backstop for (Integration.PartitionTest checks the births in rackd).
class PartitionThreadsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!CPU_ISSET(0, &before_) || !CPU_ISSET(1, &before_)) {
      GTEST_SKIP() << "needs CPUs 0 and 1 in this process's affinity";
    }
  }
  void TearDown() override { (void)sched_setaffinity(0, sizeof before_, &before_); }

  // What partition_threads() says it did, once it did something.
  static std::vector<std::string> first_moves(test::HostUnderTest& host) {
    std::vector<std::string> moved;
    EXPECT_TRUE(test::eventually([&] {
      moved = host.executor().partition_threads();  // empty until both tasks marked their start-up
      return !moved.empty();
    }));
    return moved;
  }

  Watchdog watchdog_;
  const cpu_set_t before_ = affinity_of(0);
};

// Partitioning (`cpus:`): a thread that appears after start() (a library's pool
// started on first use) is moved onto the housekeeping CPUs by partition_threads();
// the tasks keep theirs; partition_threads() reports what it moved, once.
TEST_F(PartitionThreadsTest, LateThreadsAreMovedToTheHousekeepingCpusAndTasksAreNot) {
  {
    test::HostUnderTest host(R"(system: 0
lcm: false
cpus: {rt: 1, housekeeping: 0}
components:
  - name: gen
    class: Generator
    instance: 1
    command_task: {priority: 30}
    data_task: {priority: 60, period_ms: 10}
)");
    // Started by a thread with both CPUs (this one, as a library would from anywhere).
    std::atomic<bool> stop{false};
    std::thread late([&] {
      pthread_setname_np(pthread_self(), "late-pool");
      while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    });
    pid_t late_tid = 0;
    ASSERT_TRUE(test::eventually([&] { return (late_tid = thread_named("late-pool")) != 0; }));
    const cpu_set_t inherited = affinity_of(late_tid);
    EXPECT_TRUE(CPU_ISSET(1, &inherited));
    const std::vector<std::string> moved = first_moves(host);
    ASSERT_FALSE(moved.empty());
    bool named = false;
    for (const auto& m : moved) named = named || m.find("late-pool") != std::string::npos;
    EXPECT_TRUE(named);
    const cpu_set_t l = affinity_of(late_tid);
    EXPECT_EQ(CPU_COUNT(&l), 1);
    EXPECT_TRUE(CPU_ISSET(0, &l));
    for (const char* task : {"gen:cmd", "gen:data"}) {
      const pid_t tid = thread_named(task);
      ASSERT_NE(tid, 0) << task;
      const cpu_set_t t = affinity_of(tid);
      EXPECT_EQ(CPU_COUNT(&t), 1) << task;
      EXPECT_TRUE(CPU_ISSET(1, &t)) << task << " is an RT task: it stays on the rt CPU";
    }
    EXPECT_TRUE(host.executor().partition_threads().empty()) << "a second pass has nothing to move";
    const std::string report = host.executor().thread_report();
    EXPECT_NE(report.find("threads (cpus: rt 1, housekeeping 0)"), std::string::npos) << report;
    EXPECT_NE(report.find("gen:data"), std::string::npos) << report;
    stop = true;
    late.join();
  }
}

// The backstop as rackd runs it every 100 ms: partition_new_threads() sweeps only when
// the process's thread count differs from the last complete pass's (one read of
// /proc/self/stat instead of a pass over /proc/self/task). A thread that moves itself
// onto the RT CPU without a thread being born is left until the count changes.
TEST_F(PartitionThreadsTest, TheBackstopSweepsOnlyWhenTheThreadCountChanges) {
  {
    test::HostUnderTest host(R"(system: 0
lcm: false
cpus: {rt: 1, housekeeping: 0}
components:
  - name: gen
    class: Generator
    instance: 1
    data_task: {priority: 60, period_ms: 10}
)");
    (void)first_moves(host);  // a complete pass (it moves this thread, on CPUs 0-1)
    EXPECT_TRUE(host.executor().partition_new_threads().empty()) << "no thread born since: no sweep";
    cpu_set_t rt_cpu;
    CPU_ZERO(&rt_cpu);
    CPU_SET(1, &rt_cpu);
    ASSERT_EQ(sched_setaffinity(0, sizeof rt_cpu, &rt_cpu), 0);
    EXPECT_TRUE(host.executor().partition_new_threads().empty()) << "the count did not change";
    const cpu_set_t still = affinity_of(0);
    EXPECT_TRUE(CPU_ISSET(1, &still) && CPU_COUNT(&still) == 1) << "not swept";
    std::atomic<bool> stop{false};
    std::thread late([&] {  // born on this thread's CPU 1
      while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    });
    pthread_setname_np(late.native_handle(), "late-count");
    const std::vector<std::string> moved = host.executor().partition_new_threads();
    std::string said;
    for (const auto& m : moved) said += m + "\n";
    EXPECT_NE(said.find("(late-count): moved to the housekeeping CPUs"), std::string::npos) << said;
    const cpu_set_t me = affinity_of(0);
    EXPECT_TRUE(CPU_ISSET(0, &me) && CPU_COUNT(&me) == 1) << "this thread went with the same pass";
    EXPECT_TRUE(host.executor().partition_new_threads().empty()) << "the count is the same again";
    stop = true;
    late.join();
  }
}

// A pool that a library starts from an RT task (on first use, in loop()) inherits the
// task's CPU and its SCHED_FIFO priority: partition_threads() moves it to the
// housekeeping CPUs and lowers it to SCHED_OTHER, and says so.
TEST_F(PartitionThreadsTest, APoolStartedByAnRtTaskLosesItsCpuAndItsPriority) {
  {
    test::HostUnderTest host(R"(system: 0
lcm: false
cpus: {rt: 1, housekeeping: 0}
components:
  - name: gen
    class: Generator
    instance: 1
    data_task: {priority: 60, period_ms: 10}
)");
    std::atomic<bool> stop{false};
    std::atomic<int> fifo{-1};
    std::thread pool;
    std::thread rt_caller([&] {  // as an RT task: SCHED_FIFO on the rt CPU
      cpu_set_t one;
      CPU_ZERO(&one);
      CPU_SET(1, &one);
      (void)pthread_setaffinity_np(pthread_self(), sizeof one, &one);
      const sched_param p{.sched_priority = 20};
      fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
      pool = std::thread([&] {  // the library's worker, started from the task
        pthread_setname_np(pthread_self(), "lib-pool");
        while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
      });
    });
    rt_caller.join();
    if (fifo.load() != 0) {
      stop = true;
      pool.join();
      GTEST_SKIP() << "needs SCHED_FIFO (root or CAP_SYS_NICE)";
    }
    pid_t tid = 0;
    ASSERT_TRUE(test::eventually([&] { return (tid = thread_named("lib-pool")) != 0; }));
    const cpu_set_t inherited = affinity_of(tid);
    EXPECT_EQ(CPU_COUNT(&inherited), 1);
    EXPECT_TRUE(CPU_ISSET(1, &inherited)) << "started on the RT CPU";
    EXPECT_EQ(sched_getscheduler(tid), SCHED_FIFO) << "with the task's policy";
    const std::vector<std::string> moved = first_moves(host);
    ASSERT_FALSE(moved.empty());
    std::string said;
    for (const auto& m : moved) {
      if (m.find("lib-pool") != std::string::npos) said = m;
    }
    EXPECT_NE(said.find("moved to the housekeeping CPUs"), std::string::npos) << said;
    EXPECT_NE(said.find("SCHED_FIFO 20 (inherited) lowered to SCHED_OTHER"), std::string::npos) << said;
    const cpu_set_t now = affinity_of(tid);
    EXPECT_EQ(CPU_COUNT(&now), 1);
    EXPECT_TRUE(CPU_ISSET(0, &now));
    EXPECT_EQ(sched_getscheduler(tid), SCHED_OTHER);
    const pid_t data = thread_named("gen:data");
    ASSERT_NE(data, 0);
    EXPECT_EQ(sched_getscheduler(data), SCHED_FIFO) << "the RT task keeps its policy";
    EXPECT_TRUE(host.executor().partition_threads().empty()) << "a second pass has nothing to do";
    stop = true;
    pool.join();
  }
}

}  // namespace
}  // namespace rack
