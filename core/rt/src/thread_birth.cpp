#include "rack/rt/thread_birth.h"

#include <dlfcn.h>
#include <sched.h>
#include <signal.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstddef>

#include "rack/rt/thread.h"

// Defined by rack::rt_hooks (create_hook.cpp) when the program links it: the address of
// the program's pthread_create. Weak: absent in programs without the hooks.
extern "C" __attribute__((weak)) void* rack_rt_pthread_create_hook();

namespace rack::rt::thread_birth {

namespace {

constexpr std::size_t kBitsPerWord = 64;
constexpr std::size_t kWords = CPU_SETSIZE / kBitsPerWord;

// The housekeeping CPUs, one bit each. Constant-initialized: a library's constructor may
// create a thread before this library's own constructors have run.
std::array<std::atomic<uint64_t>, kWords> g_cpus{};
// SYNC POINT: place_on() stores g_cpus, then g_on with release; create() loads g_on
// with acquire before it reads g_cpus.
std::atomic<bool> g_on{false};
std::atomic<uint64_t> g_placed{0}, g_own{0}, g_refused{0};
thread_local bool t_own = false;

cpu_set_t housekeeping() noexcept {
  cpu_set_t set;
  CPU_ZERO(&set);
  for (std::size_t w = 0; w < kWords; ++w) {
    const uint64_t bits = g_cpus[w].load(std::memory_order_relaxed);  // ordered by g_on's acquire
    for (std::size_t b = 0; b < kBitsPerWord; ++b) {
      if ((bits >> b) & 1u) CPU_SET(w * kBitsPerWord + b, &set);
    }
  }
  return set;
}

// A stack the caller gave (pthread_attr_setstack): glibc reports none as a null address
// (or, in older versions, as the top 0 less the size).
bool caller_stack(const void* addr, std::size_t size) noexcept {
  return addr != nullptr && reinterpret_cast<uintptr_t>(addr) + size != 0;
}

// `to`: the caller's attributes (or the defaults) with SCHED_OTHER on the housekeeping
// CPUs, explicitly. False when an attribute cannot be copied or set (`to` destroyed).
bool placed_attributes(const pthread_attr_t* from, pthread_attr_t& to) noexcept {
  if (pthread_attr_init(&to) != 0) return false;
  cpu_set_t cpus = housekeeping();
  bool ok = true;
  if (from != nullptr) {
    int detach = PTHREAD_CREATE_JOINABLE;
    if (pthread_attr_getdetachstate(from, &detach) == 0) ok = ok && pthread_attr_setdetachstate(&to, detach) == 0;
    std::size_t guard = 0;
    if (pthread_attr_getguardsize(from, &guard) == 0) ok = ok && pthread_attr_setguardsize(&to, guard) == 0;
    void* stack = nullptr;
    std::size_t size = 0;
    if (pthread_attr_getstack(from, &stack, &size) == 0 && caller_stack(stack, size)) {
      ok = ok && pthread_attr_setstack(&to, stack, size) == 0;
    } else if (pthread_attr_getstacksize(from, &size) == 0) {
      ok = ok && pthread_attr_setstacksize(&to, size) == 0;
    }
    sigset_t mask;
    if (pthread_attr_getsigmask_np(from, &mask) == 0) ok = ok && pthread_attr_setsigmask_np(&to, &mask) == 0;
    // CPUs the caller chose (OMP_PROC_BIND): kept where they meet the housekeeping ones.
    cpu_set_t asked;
    if (pthread_attr_getaffinity_np(from, sizeof asked, &asked) == 0) {
      cpu_set_t both;
      CPU_AND(&both, &asked, &cpus);
      if (CPU_COUNT(&both) > 0) cpus = both;
    }
  }
  const sched_param normal{};
  ok = ok && pthread_attr_setinheritsched(&to, PTHREAD_EXPLICIT_SCHED) == 0 &&
       pthread_attr_setschedpolicy(&to, SCHED_OTHER) == 0 && pthread_attr_setschedparam(&to, &normal) == 0 &&
       pthread_attr_setaffinity_np(&to, sizeof cpus, &cpus) == 0;
  if (!ok) pthread_attr_destroy(&to);
  return ok;
}

}  // namespace

int place_on(const std::vector<int>& cpus) noexcept {
  std::array<uint64_t, kWords> bits{};
  bool any = false;
  for (const int c : cpus) {
    if (c < 0 || c >= CPU_SETSIZE) continue;
    const auto cpu = static_cast<std::size_t>(c);
    bits[cpu / kBitsPerWord] |= uint64_t{1} << (cpu % kBitsPerWord);
    any = true;
  }
  if (!any) return EINVAL;
  for (std::size_t w = 0; w < kWords; ++w) g_cpus[w].store(bits[w], std::memory_order_relaxed);
  g_on.store(true, std::memory_order_release);
  return 0;
}

void stop_placing() noexcept { g_on.store(false, std::memory_order_release); }

bool placing() noexcept { return g_on.load(std::memory_order_acquire); }

bool interposed() noexcept {
  if (&rack_rt_pthread_create_hook == nullptr) return false;
  return dlsym(RTLD_DEFAULT, "pthread_create") == rack_rt_pthread_create_hook();
}

Counts counts() noexcept {
  // Relaxed: statistics, read by themselves.
  return Counts{g_placed.load(std::memory_order_relaxed), g_own.load(std::memory_order_relaxed),
                g_refused.load(std::memory_order_relaxed)};
}

std::string describe() {
  if (!interposed()) {
    return "pthread_create is not rackd's in this build (a sanitizer build leaves rack::rt_hooks out): a thread that "
           "a library or an RT task starts is born where its creator runs, and rackd moves it when the thread count "
           "changes (checked every 100 ms)";
  }
  std::string where = "where their creator asks (no partitioning)";
  if (placing()) {
    std::vector<int> cpus;
    const cpu_set_t set = housekeeping();
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(static_cast<std::size_t>(c), &set)) cpus.push_back(c);
    }
    where = "on the housekeeping CPUs (" + cpu_list_string(cpus) + ")";
  }
  return "every thread that is not an RT task or worker of the executor is born " + where +
         " with SCHED_OTHER (rackd's pthread_create); one born otherwise (glibc's own helpers, a raw clone) is moved "
         "when the thread count changes (checked every 100 ms), and rackd says so";
}

OwnThreads::OwnThreads() noexcept : saved_(t_own) { t_own = true; }
OwnThreads::~OwnThreads() { t_own = saved_; }

namespace detail {

int create(CreateFn real, pthread_t* thread, const pthread_attr_t* attr, void* (*start)(void*), void* arg) noexcept {
  if (real == nullptr) return EAGAIN;  // glibc's entry point not found: cannot happen in a dynamic program
  if (t_own) {
    g_own.fetch_add(1, std::memory_order_relaxed);
    return real(thread, attr, start, arg);
  }
  if (!g_on.load(std::memory_order_acquire)) return real(thread, attr, start, arg);
  pthread_attr_t placed;
  if (!placed_attributes(attr, placed)) {
    g_refused.fetch_add(1, std::memory_order_relaxed);
    return real(thread, attr, start, arg);
  }
  const int rc = real(thread, &placed, start, arg);
  pthread_attr_destroy(&placed);
  if (rc == EINVAL || rc == EPERM) {
    // The housekeeping CPUs were refused (a cpuset without them, one gone offline): the
    // thread is born as asked (the caller's own error, if its attributes were wrong), and
    // the sweep moves it if it can.
    g_refused.fetch_add(1, std::memory_order_relaxed);
    return real(thread, attr, start, arg);
  }
  if (rc == 0) g_placed.fetch_add(1, std::memory_order_relaxed);
  return rc;
}

}  // namespace detail

}  // namespace rack::rt::thread_birth
