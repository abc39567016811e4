// CPU partitioning from the host file (issue 20, item 2): the real rackd with
// `cpus: {rt: 1, housekeeping: 0}`. Every thread of the process is read from
// /proc/PID/task/*/status: the RT tasks may run on CPU 1 only, every other thread
// (main, GDOS, TiMS/LCM receive and send, the mode-switch reporter, the non-RT task)
// on CPU 0 only. Also: the start-up report, the overlap warning, malformed `cpus:`.
#include <gtest/gtest.h>
#include <sched.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// name and Cpus_allowed_list of every thread of `pid`, by thread id.
struct ThreadInfo {
  std::string name;
  std::string cpus;
};
std::map<int, ThreadInfo> threads_of(pid_t pid) {
  std::map<int, ThreadInfo> out;
  const std::filesystem::path dir = "/proc/" + std::to_string(pid) + "/task";
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    std::ifstream in(e.path() / "status");
    ThreadInfo t;
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("Name:", 0) == 0) t.name = line.substr(line.find_first_not_of(" \t", 5));
      if (line.rfind("Cpus_allowed_list:", 0) == 0) t.cpus = line.substr(line.find_first_not_of(" \t", 18));
    }
    if (!t.name.empty()) out[std::stoi(e.path().filename().string())] = t;
  }
  return out;
}

bool cpus_0_and_1_usable() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return false;
  return CPU_ISSET(0, &set) && CPU_ISSET(1, &set);
}

bool sched_fifo_allowed() {
  sched_param p{};
  p.sched_priority = 1;
  // A short-lived probe on a helper thread would be cleaner; the test process itself
  // gives the priority straight back.
  if (sched_setscheduler(0, SCHED_FIFO, &p) != 0) return false;
  p.sched_priority = 0;
  sched_setscheduler(0, SCHED_OTHER, &p);
  return true;
}

std::string host_file(const std::string& url, const std::string& cpus) {
  return "host: partition-test\nsystem: 0\nlcm_url: \"" + url + "\"\n" + cpus +
         "components:\n"
         "  - name: control\n"
         "    class: Generator\n"
         "    instance: 0\n"
         "    autostart: true\n"
         "    command_task: {priority: 70}\n"
         "    data_task: {priority: 80, period_ms: 1}\n"
         "  - name: background\n"
         "    class: Generator\n"
         "    instance: 1\n"
         "    autostart: true\n"
         "    command_task: {priority: 30}\n"
         "    data_task: {priority: 0, period_ms: 20}\n";
}

class PartitionTest : public ::testing::Test {
 protected:
  PartitionTest() : watchdog_(60s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void SetUp() override {
    if (!cpus_0_and_1_usable()) GTEST_SKIP() << "needs CPUs 0 and 1 in this process's affinity";
    if (!sched_fifo_allowed()) GTEST_SKIP() << "needs SCHED_FIFO (root or CAP_SYS_NICE)";
  }
  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
};

TEST_F(PartitionTest, EveryNonRtThreadRunsOnTheHousekeepingCpus) {
  const auto file = dir_.write("part.yaml", host_file(bus_.url(), "cpus: {rt: 1, housekeeping: 0}\n"));
  Process rackd({kRackd, file.string()}, dir_.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 20s)) << rackd.err();
  // rackctl on the same bus: its requests exercise the receive and send threads.
  const RunResult st = run({kRackctl, "--lcm", bus_.url(), "status", "control"}, 20s);
  EXPECT_EQ(st.exit_code, 0) << st.out << st.err;

  const std::set<std::string> rt_tasks{"control:cmd", "control:data", "background:cmd"};
  const auto threads = threads_of(rackd.pid());
  std::set<std::string> seen;
  for (const auto& [tid, t] : threads) {
    seen.insert(t.name);
    if (rt_tasks.count(t.name) != 0) {
      EXPECT_EQ(t.cpus, "1") << "RT task " << t.name << " (" << tid << ")";
    } else {
      EXPECT_EQ(t.cpus, "0") << "thread " << t.name << " (" << tid << ") is not an RT task";
    }
  }
  // The threads the test means to cover are there (names as rackd gives them).
  for (const char* name : {"control:cmd", "control:data", "background:cmd", "background:data", "rackd:gdos", "tims-rx",
                           "tims-tx", "rack-reporter", "rackd"}) {
    EXPECT_EQ(seen.count(name), 1u) << "no thread named " << name;
  }
  // The start-up report says where each thread runs.
  const std::string err = rackd.err();
  EXPECT_TRUE(contains(err, "rackd: cpus: RT tasks on CPU 1, housekeeping on CPU 0")) << err;
  EXPECT_TRUE(contains(err, "threads (cpus: rt 1, housekeeping 0)")) << err;
  EXPECT_TRUE(contains(err, "control:data")) << err;
  EXPECT_FALSE(contains(err, "serves RT tasks and housekeeping alike")) << err;

  // rackctl threads PID shows the same.
  const RunResult th = run({kRackctl, "threads", std::to_string(rackd.pid())}, 20s);
  EXPECT_EQ(th.exit_code, 0) << th.out << th.err;
  EXPECT_TRUE(contains(th.out, "control:data")) << th.out;
  EXPECT_TRUE(contains(th.out, "FIFO 80")) << th.out;

  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), 0) << rackd.err();
}

// A driver's blocking device I/O (LadarSick's TCP link) runs in an executor-owned I/O
// worker: on the housekeeping CPU, and the start-up listing says what it is.
TEST_F(PartitionTest, ADriversIoWorkerRunsOnTheHousekeepingCpus) {
  const auto file = dir_.write("part.yaml", host_file(bus_.url(), "cpus: {rt: 1, housekeeping: 0}\n") +
                                                "  - name: sick\n"
                                                "    class: LadarSick\n"
                                                "    instance: 0\n"
                                                "    data_task: {period_ms: 10}\n"
                                                "    params: {host: 127.0.0.1, port: 9}\n");
  Process rackd({kRackd, file.string()}, dir_.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 20s)) << rackd.err();
  int workers = 0;
  for (const auto& [tid, t] : threads_of(rackd.pid())) {
    if (t.name != "tcp-sensor") continue;
    ++workers;
    EXPECT_EQ(t.cpus, "0") << "the I/O worker (" << tid << ") is not an RT task";
  }
  EXPECT_EQ(workers, 1) << "LadarSick's link runs in one I/O worker";
  const std::string err = rackd.err();
  const auto at = err.find("tcp-sensor");
  ASSERT_NE(at, std::string::npos) << err;
  EXPECT_NE(err.substr(at, err.find('\n', at) - at).find("I/O worker, not RT"), std::string::npos) << err;
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), 0) << rackd.err();
}

// The line of `text` that holds `part` ("" when none).
std::string line_with(const std::string& text, const std::string& part) {
  const auto at = text.find(part);
  if (at == std::string::npos) return "";
  const auto begin = text.rfind('\n', at);
  const auto start = begin == std::string::npos ? 0 : begin + 1;
  return text.substr(start, text.find('\n', at) - start);
}

// Threads that an RT task of a plug-in starts in a cycle (rack_thread_birth_plugin: a
// pthread, a detached one with a 512 KiB stack, a std::thread and an OpenMP region's
// worker, libgomp coming in with the plug-in's dlopen()) are born on the housekeeping
// CPU with SCHED_OTHER: each reads /proc/self/task/TID/ first thing, before any sweep
// could have moved it. rackd's pthread_create placed them (rack/rt/thread_birth.h), so
// the sweep names none; the detached thread keeps the attributes its creator gave it.
TEST_F(PartitionTest, ThreadsAnRtTaskStartsAreBornOnTheHousekeepingCpus) {
  // Threads created in a cycle are a mode switch, here on purpose: detection is off for
  // that task.
  const std::string text = "host: partition-test\nsystem: 0\nlcm_url: \"" + bus_.url() + "\"\n" + "plugins: [" +
                           RACK_THREAD_BIRTH_PLUGIN_PATH + "]\n" +
                           "cpus: {rt: 1, housekeeping: 0}\n"
                           "components:\n"
                           "  - name: starter\n"
                           "    class: ThreadStarter\n"
                           "    instance: 0\n"
                           "    autostart: true\n"
                           "    command_task: {priority: 70}\n"
                           "    data_task: {priority: 80, period_ms: 10, modeswitch: off}\n";
  const auto file = dir_.write("birth.yaml", text);
  Process rackd({kRackd, file.string()}, dir_.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 20s)) << rackd.err();
  if (contains(rackd.err(), "pthread_create is not rackd's in this build")) {
    GTEST_SKIP() << "rackd was built without rack::rt_hooks (a sanitizer build): threads are moved, not born right";
  }
  std::vector<std::string> kinds{"pthread", "pthread-attr", "std::thread"};
#ifdef RACK_TEST_OPENMP
  kinds.emplace_back("openmp");
#endif
  for (const auto& kind : kinds) {
    ASSERT_TRUE(rackd.wait_for_stderr("thread-birth: " + kind + ": ", 20s)) << kind << "\n" << rackd.err();
  }
  const std::string err = rackd.err();
  for (const auto& kind : kinds) {
    const std::string line = line_with(err, "thread-birth: " + kind + ": ");
    EXPECT_TRUE(contains(line, "CPUs 0, policy 0, priority 0")) << line;
  }
  const std::string attr = line_with(err, "thread-birth: pthread-attr: ");
  EXPECT_TRUE(contains(attr, "detached 1")) << attr;
  const auto stack_at = attr.find("stack ");
  ASSERT_NE(stack_at, std::string::npos) << attr;
  const long stack_kib = std::strtol(attr.c_str() + stack_at + 6, nullptr, 10);
  EXPECT_GE(stack_kib, 512) << attr;
  EXPECT_LT(stack_kib, 1024) << "the creator's 512 KiB, not the 8 MiB default: " << attr;
  EXPECT_TRUE(contains(err, "is born on the housekeeping CPUs (0) with SCHED_OTHER (rackd's pthread_create)")) << err;
  EXPECT_FALSE(contains(err, "(it was not born there)")) << err;
  // The task that started them is still the RT task on CPU 1.
  bool seen = false;
  for (const auto& [tid, t] : threads_of(rackd.pid())) {
    if (t.name != "starter:data") continue;
    seen = true;
    EXPECT_EQ(t.cpus, "1") << "RT task starter:data (" << tid << ")";
  }
  EXPECT_TRUE(seen) << "no thread named starter:data";
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), 0) << rackd.err();
}

TEST_F(PartitionTest, WarnsWhenAnRtCpuAlsoServesHousekeeping) {
  const auto file = dir_.write("overlap.yaml", host_file(bus_.url(), "cpus: {rt: \"0-1\", housekeeping: [1]}\n"));
  Process rackd({kRackd, file.string(), "--duration", "1"}, dir_.path(), "rackd");
  ASSERT_EQ(rackd.wait_exit(30s), 0) << rackd.err();
  EXPECT_TRUE(contains(rackd.err(), "WARNING: cpus: CPU 1 serves RT tasks and housekeeping alike")) << rackd.err();
}

TEST_F(PartitionTest, MalformedCpusAreRefusedWithTheirPlace) {
  struct Case {
    std::string cpus;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"cpus: {rt: 4000}\n", "'cpus: rt': CPU 4000 is not online"},
      {"cpus: {rt: \"1-\"}\n", "'cpus: rt' must be a CPU number, a list of them or a CPU list"},
      {"cpus: {housekeeping: [0, x]}\n", "'cpus: housekeeping' must be a CPU number"},
      {"cpus: {rt: 1, cores: 0}\n", "cores"},
      {"cpus: 1\n", "'cpus' must be a map (rt, housekeeping)"},
      {"cpus: {}\n", "'cpus' needs 'rt' or 'housekeeping'"},
  };
  for (const auto& c : cases) {
    const auto file = dir_.write("bad.yaml", host_file(bus_.url(), c.cpus));
    const RunResult r = run({kRackd, "--check", file.string()}, 20s);
    EXPECT_EQ(r.exit_code, 2) << c.cpus << r.err;
    EXPECT_TRUE(contains(r.err, "bad.yaml:4:")) << c.cpus << r.err;
    EXPECT_TRUE(contains(r.err, c.message)) << c.cpus << r.err;
  }
}

}  // namespace
}  // namespace rack::test
