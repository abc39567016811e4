// Where threads are born (issue 20 item 2): with CPU partitioning every thread that is
// not one of the executor's own (its tasks and workers, rt::Thread) must run on the
// housekeeping CPUs with SCHED_OTHER, whoever starts it: our code, a library (LCM's
// GLib thread, OpenMP's or TBB's pool, MRPT's workers) or a plug-in, and also when an
// RT task starts it (a pool started on first use in loop()). Such a thread would
// otherwise inherit the creator's CPUs and its SCHED_FIFO priority.
//
// How: the program defines pthread_create (rack::rt_hooks, core/rt/src/create_hook.cpp).
// A definition in the executable is the one the dynamic linker binds for every shared
// library, those loaded later with dlopen() included (libstdc++'s std::thread, libgomp,
// libtbb, GLib, plug-ins). It calls create() below, which, while place_on() is in
// force, gives the new thread explicit attributes: the caller's own (stack, guard,
// detach state, signal mask) plus PTHREAD_EXPLICIT_SCHED, SCHED_OTHER and the
// housekeeping CPUs (intersected with CPUs the caller asked for, when they meet).
// glibc applies both before the thread runs any of its code (it holds the new thread
// until the creator has set them). Threads created inside OwnThreads (rt::Thread: the
// executor's tasks and workers; the capabilities probe) keep the attributes they ask for.
//
// Weighed and not chosen: SCHED_FLAG_RESET_ON_FORK on the RT tasks makes their children
// SCHED_OTHER but leaves them on the task's CPU (the mask is inherited), and
// sched_getscheduler() then reports the flag in the policy; pthread_setattr_default_np()
// applies only to threads created without attributes (not libgomp's, which pass theirs).
// What the interposer cannot see (glibc's internal helper threads, a raw clone(), a
// sanitizer build, which leaves rack::rt_hooks out): the executor's sweep
// (Executor::partition_new_threads) moves those after the fact.
//
// Real-time contract: nothing here is RT-safe. create() runs only when a thread is
// created, which is itself a mode switch (clone, mmap of the stack); no RT path of the
// executor creates threads.
// Thread-safety: place_on() and stop_placing() from one thread (the executor's start()
// and stop()); create(), counts() and interposed() from any thread.
#pragma once

#include <pthread.h>

#include <cstdint>
#include <string>
#include <vector>

namespace rack::rt::thread_birth {

// From now on threads are born on `cpus` with SCHED_OTHER (where pthread_create is
// interposed). Returns EINVAL (and changes nothing) for an empty list. Not RT-safe.
int place_on(const std::vector<int>& cpus) noexcept;
// Threads are born as their creator asks again. Not RT-safe.
void stop_placing() noexcept;
// place_on() is in force.
[[nodiscard]] bool placing() noexcept;

// This program's pthread_create is rack's (rack::rt_hooks linked and exported, so that
// the dynamic linker binds it for every library). Not RT-safe (dlsym).
[[nodiscard]] bool interposed() noexcept;

// How many threads create() has seen since the process started.
struct Counts {
  uint64_t placed = 0;   // born on the housekeeping CPUs with SCHED_OTHER
  uint64_t own = 0;      // inside OwnThreads (the executor's tasks and workers): as asked
  uint64_t refused = 0;  // the placement failed (a cpuset without those CPUs): born as asked
};
[[nodiscard]] Counts counts() noexcept;

// One line for rackd's start-up output: what happens to new threads, and why.
[[nodiscard]] std::string describe();

// While one lives, the threads that the calling thread creates keep the attributes they
// ask for (rt::Thread::start: the executor's tasks and workers get theirs from the host
// file). Nests. Not RT-safe (a thread-local flag; it is the creation that is not).
class OwnThreads {
 public:
  OwnThreads() noexcept;
  ~OwnThreads();
  OwnThreads(const OwnThreads&) = delete;
  OwnThreads& operator=(const OwnThreads&) = delete;

 private:
  bool saved_;
};

namespace detail {
using CreateFn = int (*)(pthread_t*, const pthread_attr_t*, void* (*)(void*), void*);
// The interposer's body: `real` is glibc's pthread_create. Returns what it returns.
int create(CreateFn real, pthread_t* thread, const pthread_attr_t* attr, void* (*start)(void*), void* arg) noexcept;
}  // namespace detail

}  // namespace rack::rt::thread_birth
