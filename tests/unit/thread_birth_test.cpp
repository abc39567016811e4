// Where threads are born (rack/rt/thread_birth.h): this binary links rackd's
// pthread_create (rack::rt_hooks), so with place_on() a thread that an RT thread on CPU 1
// starts (a pthread, a detached one with its own stack, a std::thread, an OpenMP region's
// worker) is born on CPU 0 with SCHED_OTHER. Each new thread reads itself from
// /proc/self/task/TID/ as its first act: what glibc started, before anything could move
// it. Threads created inside OwnThreads (the executor's tasks) and after stop_placing()
// inherit their creator's CPU and policy as usual. Integration.PartitionTest checks the
// same in rackd with a plug-in.
#include <pthread.h>
#include <sched.h>
#include <unistd.h>
#ifdef RACK_TEST_OPENMP
#include <omp.h>
#endif

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "rack/rt/thread_birth.h"
#include "test_support.h"

namespace rack {
namespace {

using test::Watchdog;

// A thread as the kernel has it: Cpus_allowed_list, policy and rt_priority (stat fields
// 41 and 40), read by the thread itself.
struct Birth {
  std::string cpus = "?";
  long policy = -1;
  long priority = -1;
  int detach = -1;        // from pthread_getattr_np
  std::size_t stack = 0;  // bytes
  std::atomic<bool> done{false};
};

void read_birth(Birth& b) {
  const std::string dir = "/proc/self/task/" + std::to_string(gettid()) + "/";
  std::ifstream status(dir + "status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("Cpus_allowed_list:", 0) == 0) b.cpus = line.substr(line.find_first_not_of(" \t", 18));
  }
  std::ifstream stat_file(dir + "stat");
  std::getline(stat_file, line);
  if (const auto close = line.rfind(')'); close != std::string::npos) {
    int field = 2;
    for (std::size_t i = close + 1; i < line.size(); ++i) {
      if (line[i] != ' ') continue;
      ++field;
      if (field == 40) b.priority = std::strtol(line.c_str() + i + 1, nullptr, 10);
      if (field == 41) b.policy = std::strtol(line.c_str() + i + 1, nullptr, 10);
    }
  }
  pthread_attr_t attr;
  if (pthread_getattr_np(pthread_self(), &attr) == 0) {
    (void)pthread_attr_getdetachstate(&attr, &b.detach);
    (void)pthread_attr_getstacksize(&attr, &b.stack);
    pthread_attr_destroy(&attr);
  }
  b.done.store(true, std::memory_order_release);
}

void* read_birth_entry(void* b) {
  read_birth(*static_cast<Birth*>(b));
  return nullptr;
}

class ThreadBirthTest : public ::testing::Test {
 protected:
  void SetUp() override {
    cpu_set_t set;
    CPU_ZERO(&set);
    if (sched_getaffinity(0, sizeof set, &set) != 0 || !CPU_ISSET(0, &set) || !CPU_ISSET(1, &set)) {
      GTEST_SKIP() << "needs CPUs 0 and 1 in this process's affinity";
    }
    if (!rt::thread_birth::interposed()) GTEST_SKIP() << "pthread_create is not rack's in this build";
  }
  void TearDown() override { rt::thread_birth::stop_placing(); }

  // Runs `body` on a thread that is SCHED_FIFO 20 on CPU 1, as an RT task of the
  // executor is (created inside OwnThreads, as rt::Thread does). False when SCHED_FIFO
  // is refused.
  static bool as_rt_task(const std::function<void()>& body) {
    std::atomic<bool> fifo{false};
    std::thread task;
    {
      const rt::thread_birth::OwnThreads own;
      task = std::thread([&] {
        cpu_set_t one;
        CPU_ZERO(&one);
        CPU_SET(1, &one);
        (void)pthread_setaffinity_np(pthread_self(), sizeof one, &one);
        const sched_param p{.sched_priority = 20};
        if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &p) != 0) return;
        fifo = true;
        body();
      });
    }
    task.join();
    return fifo.load();
  }

  static void wait_for(const Birth& b) {
    while (!b.done.load(std::memory_order_acquire)) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

  Watchdog watchdog_;
};

TEST_F(ThreadBirthTest, ThreadsAnRtThreadStartsAreBornOnTheHousekeepingCpu) {
  ASSERT_EQ(rt::thread_birth::place_on({0}), 0);
  const auto before = rt::thread_birth::counts();
  Birth plain, detached, standard, openmp;
  bool detached_started = false;
  const bool fifo = as_rt_task([&] {
    pthread_t t;
    ASSERT_EQ(pthread_create(&t, nullptr, &read_birth_entry, &plain), 0);
    pthread_join(t, nullptr);
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
    pthread_attr_setstacksize(&attr, 512 * 1024);
    pthread_t d;
    detached_started = pthread_create(&d, &attr, &read_birth_entry, &detached) == 0;
    pthread_attr_destroy(&attr);
    std::thread([&] { read_birth(standard); }).join();
#ifdef RACK_TEST_OPENMP
#pragma omp parallel num_threads(2)
    {
      if (omp_get_thread_num() == 1) read_birth(openmp);
    }
#endif
  });
  if (!fifo) GTEST_SKIP() << "needs SCHED_FIFO (root or CAP_SYS_NICE)";
  ASSERT_TRUE(detached_started);
  wait_for(detached);
  std::vector<std::pair<const char*, Birth*>> born{
      {"pthread", &plain}, {"detached", &detached}, {"std::thread", &standard}};
#ifdef RACK_TEST_OPENMP
  born.emplace_back("openmp", &openmp);
#endif
  for (const auto& [kind, b] : born) {
    ASSERT_TRUE(b->done.load()) << kind;
    EXPECT_EQ(b->cpus, "0") << kind << ": born on the housekeeping CPU, not its creator's CPU 1";
    EXPECT_EQ(b->policy, SCHED_OTHER) << kind << ": not its creator's SCHED_FIFO";
    EXPECT_EQ(b->priority, 0) << kind;
  }
  EXPECT_EQ(detached.detach, PTHREAD_CREATE_DETACHED) << "the creator's attributes are kept";
  EXPECT_GE(detached.stack, 512u * 1024u);
  EXPECT_LT(detached.stack, 1024u * 1024u) << "the creator's 512 KiB, not the default";
  EXPECT_EQ(plain.detach, PTHREAD_CREATE_JOINABLE);
  EXPECT_GE(rt::thread_birth::counts().placed - before.placed, born.size());
  EXPECT_NE(rt::thread_birth::describe().find("born on the housekeeping CPUs (0) with SCHED_OTHER"), std::string::npos)
      << rt::thread_birth::describe();
}

TEST_F(ThreadBirthTest, OwnThreadsAndThreadsAfterStopPlacingInheritTheirCreators) {
  ASSERT_EQ(rt::thread_birth::place_on({0}), 0);
  Birth own, after;
  const bool fifo = as_rt_task([&] {
    {
      const rt::thread_birth::OwnThreads keep;  // as rt::Thread::start does for the tasks
      std::thread([&] { read_birth(own); }).join();
    }
    rt::thread_birth::stop_placing();
    std::thread([&] { read_birth(after); }).join();
  });
  if (!fifo) GTEST_SKIP() << "needs SCHED_FIFO (root or CAP_SYS_NICE)";
  for (const auto* b : {&own, &after}) {
    EXPECT_EQ(b->cpus, "1");
    EXPECT_EQ(b->policy, SCHED_FIFO);
    EXPECT_EQ(b->priority, 20);
  }
  EXPECT_FALSE(rt::thread_birth::placing());
}

}  // namespace
}  // namespace rack
