// A component class in a plug-in whose RT data task starts threads in its first cycle,
// as a library's pool started on first use would (issue 20 item 2, PartitionTest): a
// pthread without attributes, a detached pthread with a 512 KiB stack, a std::thread
// and, built with OpenMP, the worker of a two-thread parallel region (libgomp, loaded
// with this plug-in by dlopen()). Each new thread reads where it was born from
// /proc/self/task/TID/ before it does anything else and writes one line to stderr:
//   thread-birth: KIND: tid T, CPUs LIST, policy P, priority R[, detached D, stack S]
// so that the test sees the thread as glibc started it, before any sweep could move it,
// and names itself tb-KIND (libgomp's worker lives on, with the data task's name otherwise).
// Deliberately not RT code: creating threads in a cycle is a mode switch (the host file
// of the test switches detection off for this task).
#include <pthread.h>
#include <unistd.h>
#ifdef RACK_TEST_OPENMP
#include <omp.h>
#endif

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include "rack/core/class_types.h"
#include "rack/core/data_component.h"
#include "rack/core/registry.h"

namespace {

struct StarterData {
  int64_t started = 0;  // threads started
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(StarterData, started)}; }
};
const rack::DataTypeInfo kStarterDataInfo = rack::data_type_info<StarterData>("ThreadStarterData");

// The calling thread as the kernel has it now, on one line of stderr.
void report_birth(const char* kind, bool with_attributes) {
  const auto tid = static_cast<long>(gettid());
  const std::string dir = "/proc/self/task/" + std::to_string(tid) + "/";
  std::string cpus = "?", line;
  std::ifstream status(dir + "status");
  while (std::getline(status, line)) {
    if (line.rfind("Cpus_allowed_list:", 0) == 0) cpus = line.substr(line.find_first_not_of(" \t", 18));
  }
  long policy = -1, priority = -1;
  std::ifstream stat_file(dir + "stat");
  std::getline(stat_file, line);
  // Fields after the name (in parentheses, which may hold spaces): 3 state ... 40
  // rt_priority, 41 policy.
  if (const auto close = line.rfind(')'); close != std::string::npos) {
    int field = 2;
    for (std::size_t i = close + 1; i < line.size(); ++i) {
      if (line[i] != ' ') continue;
      ++field;
      if (field == 40) priority = std::strtol(line.c_str() + i + 1, nullptr, 10);
      if (field == 41) policy = std::strtol(line.c_str() + i + 1, nullptr, 10);
    }
  }
  std::string extra;
  if (with_attributes) {  // what the creator asked for survived the placement
    pthread_attr_t attr;
    if (pthread_getattr_np(pthread_self(), &attr) == 0) {
      int detach = -1;
      std::size_t stack = 0;
      (void)pthread_attr_getdetachstate(&attr, &detach);
      (void)pthread_attr_getstacksize(&attr, &stack);
      pthread_attr_destroy(&attr);
      extra = ", detached " + std::to_string(detach == PTHREAD_CREATE_DETACHED ? 1 : 0) + ", stack " +
              std::to_string(stack / 1024) + " KiB";
    }
  }
  // A name of its own (it inherited the data task's): the test tells the task from it.
  // Before the line, so that the name is set when the test reads it.
  pthread_setname_np(pthread_self(), ("tb-" + std::string(kind)).substr(0, 15).c_str());
  char text[256];
  const int n = std::snprintf(text, sizeof text, "thread-birth: %s: tid %ld, CPUs %s, policy %ld, priority %ld%s\n",
                              kind, tid, cpus.c_str(), policy, priority, extra.c_str());
  if (n <= 0) return;
  const std::size_t length = std::min(static_cast<std::size_t>(n), sizeof text - 1);
  (void)!::write(STDERR_FILENO, text, length);  // one write: the line stays whole
}

void* plain_thread(void*) {
  report_birth("pthread", false);
  return nullptr;
}

void* attr_thread(void*) {
  report_birth("pthread-attr", true);
  return nullptr;
}

class ThreadStarter final : public rack::DataComponent<StarterData> {
 public:
  ThreadStarter() : DataComponent(rack::DataTaskMode::kPeriodic) {}

 protected:
  rack::HookResult loop() override {
    if (started_.exchange(true, std::memory_order_relaxed)) return rack::HookResult::kOk;
    StarterData d;
    if (pthread_create(&plain_, nullptr, &plain_thread, nullptr) == 0) {
      plain_started_ = true;
      ++d.started;
    }
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
    pthread_attr_setstacksize(&attr, 512 * 1024);
    pthread_t detached;
    if (pthread_create(&detached, &attr, &attr_thread, nullptr) == 0) ++d.started;
    pthread_attr_destroy(&attr);
    std_thread_ = std::thread([] { report_birth("std::thread", false); });
    ++d.started;
#ifdef RACK_TEST_OPENMP
#pragma omp parallel num_threads(2)
    {
      if (omp_get_thread_num() == 1) report_birth("openmp", false);
    }
    ++d.started;
#endif
    publish(d, rack::rt::host_time_ns());
    return rack::HookResult::kOk;
  }
  void cleanup() override {
    if (plain_started_) pthread_join(plain_, nullptr);
    plain_started_ = false;
    if (std_thread_.joinable()) std_thread_.join();
  }

 private:
  std::atomic<bool> started_{false};
  pthread_t plain_{};
  bool plain_started_ = false;
  std::thread std_thread_;
};

}  // namespace

extern "C" void rack_register_components(rack::ComponentRegistry& registry) {
  rack::ComponentClass cls{"ThreadStarter", 0x93, "test: a plug-in class whose data task starts threads",
                           [] { return std::make_unique<ThreadStarter>(); }};
  cls.data = &kStarterDataInfo;
  registry.add(std::move(cls));
}
