// The one place that owns the process memory policy (STYLE.md 6, cactus-rt's App::Start).
//
// Not real-time safe: call once at start-up, before real-time tasks run.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

// A ThreadSanitizer build (RACK_SANITIZER=thread) cannot live with the memory
// policy: TSan reserves tens of TiB of shadow memory (mlockall would try to make it
// all resident) and keeps ~768 KiB of per-thread state in static TLS, which glibc
// carves out of every thread's stack (pre-faulting 3/4 of a 256 KiB task stack runs
// past its end). There the policy locks nothing, pre-faults nothing and gives each
// task thread room for TSan's TLS on top of its stack_bytes; it says so once on stderr.
#if defined(__SANITIZE_THREAD__)
#define RACK_RT_THREAD_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define RACK_RT_THREAD_SANITIZER 1
#endif
#endif
#ifndef RACK_RT_THREAD_SANITIZER
#define RACK_RT_THREAD_SANITIZER 0
#endif

namespace rack::rt {

inline constexpr bool kThreadSanitizer = RACK_RT_THREAD_SANITIZER != 0;

struct MemoryPolicyResult {
  bool locked = false;  // mlockall(MCL_CURRENT | MCL_FUTURE) succeeded
  int lock_errno = 0;   // errno of mlockall when it failed
  std::size_t prefaulted_heap_bytes = 0;
  bool skipped_for_sanitizer = false;  // ThreadSanitizer build: nothing locked or pre-faulted
  [[nodiscard]] std::string describe() const;
};

// Locks all current and future pages, keeps the heap from ever shrinking or using
// mmap (so free() never calls sbrk/munmap in an RT task: glibc trims the top of the
// heap with sbrk once free space exceeds M_TRIM_THRESHOLD, see mallopt(3)), and
// touches `heap_prefault_bytes` of heap so later allocations do not page-fault.
// Idempotent. Not RT-safe. In a ThreadSanitizer build it does none of this (see
// above) and returns skipped_for_sanitizer.
// Threads created afterwards without an explicit stack size (the service threads:
// TiMS receive/send, GDOS, the mode-switch reporter; a library's own) get
// kServiceThreadStackBytes instead of RLIMIT_STACK's 8 MiB, which mlockall would lock
// and fault in whole for each of them. RT tasks set their own (host file stack_kib).
inline constexpr std::size_t kServiceThreadStackBytes = std::size_t{1} << 20;
// Sets that default stack size now (rackd calls it first thing, before its first
// thread). Not RT-safe.
void limit_default_thread_stack() noexcept;
MemoryPolicyResult apply_memory_policy(std::size_t heap_prefault_bytes) noexcept;

// Unlocks (munlock) every mapping of the files named in `paths` (as /proc/self/maps
// names them): libraries that only non-RT work uses (a plug-in's MRPT). Returns the
// bytes unlocked. Not RT-safe.
std::size_t unlock_file_mappings(const std::vector<std::string>& paths) noexcept;

// Touches `bytes` of the calling thread's stack so it is resident (call at task
// start, before the first cycle). Not RT-safe by intent: it is the warm-up.
// A no-op in a ThreadSanitizer build.
void prefault_stack(std::size_t bytes) noexcept;

// ThreadSanitizer build only: says once per process, on stderr, what the memory
// policy leaves out. A no-op in other builds.
void note_sanitizer_memory_policy() noexcept;

// ThreadSanitizer build: the static TLS of every loaded object (TSan's own is most
// of it), which glibc takes from each new thread's stack. 0 in other builds.
std::size_t sanitizer_stack_extra_bytes() noexcept;

}  // namespace rack::rt
