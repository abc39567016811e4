#include "rack/rt/thread.h"

#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "rack/rt/memory.h"
#include "rack/rt/thread_birth.h"

namespace rack::rt {

namespace {

int create(pthread_t* handle, const ThreadConfig& config, bool realtime, void* (*fn)(void*), void* arg) {
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  const auto min_stack = static_cast<std::size_t>(PTHREAD_STACK_MIN);
  // ThreadSanitizer build: glibc takes TSan's large static TLS from the stack.
  const std::size_t stack = config.stack_bytes + sanitizer_stack_extra_bytes();
  pthread_attr_setstacksize(&attr, stack < min_stack ? min_stack : stack);
  if (realtime) {
    // Explicit: without it the new thread inherits the creator's policy and the
    // attributes below are silently ignored.
    pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
    pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
    sched_param param{};
    param.sched_priority = config.priority;
    pthread_attr_setschedparam(&attr, &param);
  } else {
    pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
    pthread_attr_setschedpolicy(&attr, SCHED_OTHER);
    sched_param param{};
    pthread_attr_setschedparam(&attr, &param);
  }
  if (config.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<std::size_t>(config.cpu), &set);
    pthread_attr_setaffinity_np(&attr, sizeof(set), &set);
  } else if (!config.cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (const int c : config.cpus) {
      if (c >= 0 && c < CPU_SETSIZE) CPU_SET(static_cast<std::size_t>(c), &set);
    }
    if (CPU_COUNT(&set) > 0) pthread_attr_setaffinity_np(&attr, sizeof(set), &set);
  }
  const int rc = pthread_create(handle, &attr, fn, arg);
  pthread_attr_destroy(&attr);
  return rc;
}

}  // namespace

Thread::~Thread() {
  if (started_) join();
}

void* Thread::trampoline(void* self) {
  auto* thread = static_cast<Thread*>(self);
  pthread_setname_np(pthread_self(), thread->config_.name.substr(0, 15).c_str());
  // Touch most of the stack now, so the first cycles do not fault it in.
  prefault_stack(thread->config_.stack_bytes * 3 / 4);
  thread->body_();
  return nullptr;
}

ThreadStart Thread::start(const ThreadConfig& config, std::function<void()> body, bool allow_fallback) {
  config_ = config;
  body_ = std::move(body);
  note_sanitizer_memory_policy();
  const bool want_rt = config.priority > 0;
  // The executor's own threads get their CPUs and policy from the host file, not the
  // housekeeping placement of threads that others start (rack/rt/thread_birth.h).
  const thread_birth::OwnThreads own;
  int rc = create(&handle_, config_, want_rt, &Thread::trampoline, this);
  ThreadStart how = want_rt ? ThreadStart::kRealTime : ThreadStart::kNormal;
  if (rc == EPERM && want_rt && allow_fallback) {
    rc = create(&handle_, config_, false, &Thread::trampoline, this);
    how = ThreadStart::kFallback;
  }
  if (rc != 0) {
    throw std::system_error(rc, std::generic_category(),
                            "cannot start thread '" + config.name + "' (priority " + std::to_string(config.priority) +
                                ", cpu " + std::to_string(config.cpu) + ")");
  }
  started_ = true;
  return how;
}

void Thread::join() {
  if (!started_) return;
  pthread_join(handle_, nullptr);
  started_ = false;
}

int set_current_thread_priority(int priority) noexcept {
  sched_param param{};
  param.sched_priority = priority;
  return pthread_setschedparam(pthread_self(), priority > 0 ? SCHED_FIFO : SCHED_OTHER, &param);
}

int set_thread_affinity(pid_t tid, const std::vector<int>& cpus) noexcept {
  cpu_set_t set;
  CPU_ZERO(&set);
  for (const int c : cpus) {
    if (c >= 0 && c < CPU_SETSIZE) CPU_SET(static_cast<std::size_t>(c), &set);
  }
  if (CPU_COUNT(&set) == 0) return EINVAL;
  return sched_setaffinity(tid, sizeof set, &set) == 0 ? 0 : errno;
}

std::string cpu_list_string(std::vector<int> cpus) {
  std::sort(cpus.begin(), cpus.end());
  cpus.erase(std::unique(cpus.begin(), cpus.end()), cpus.end());
  std::string out;
  for (std::size_t i = 0; i < cpus.size();) {
    std::size_t j = i;
    while (j + 1 < cpus.size() && cpus[j + 1] == cpus[j] + 1) ++j;
    if (!out.empty()) out += ',';
    out += std::to_string(cpus[i]);
    if (j > i) out += '-' + std::to_string(cpus[j]);
    i = j + 1;
  }
  return out;
}

long process_thread_count() noexcept {
  const int fd = ::open("/proc/self/stat", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  char line[1024];  // num_threads (field 20) is well within the first 1024 bytes
  const ssize_t n = ::read(fd, line, sizeof line - 1);
  ::close(fd);
  if (n <= 0) return -1;
  line[n] = '\0';
  // Field 2, the name, is in parentheses and may hold spaces and ')': count from the last one.
  const char* p = std::strrchr(line, ')');
  if (p == nullptr) return -1;
  int field = 2;
  for (; *p != '\0'; ++p) {
    if (*p != ' ') continue;
    if (++field == 20) {
      char* end = nullptr;
      const long count = std::strtol(p + 1, &end, 10);
      return end != p + 1 && count > 0 ? count : -1;
    }
  }
  return -1;
}

}  // namespace rack::rt
