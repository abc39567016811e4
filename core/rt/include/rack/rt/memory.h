// The one place that owns the process memory policy (STYLE.md 6, cactus-rt's App::Start).
//
// Not real-time safe: call once at start-up, before real-time tasks run.
#pragma once

#include <cstddef>
#include <string>

namespace rack::rt {

struct MemoryPolicyResult {
  bool locked = false;      // mlockall(MCL_CURRENT | MCL_FUTURE) succeeded
  int lock_errno = 0;       // errno of mlockall when it failed
  std::size_t prefaulted_heap_bytes = 0;
  [[nodiscard]] std::string describe() const;
};

// Locks all current and future pages, keeps the heap from ever shrinking or using
// mmap (so free() never calls sbrk/munmap in an RT task: glibc trims the top of the
// heap with sbrk once free space exceeds M_TRIM_THRESHOLD, see mallopt(3)), and
// touches `heap_prefault_bytes` of heap so later allocations do not page-fault.
// Idempotent. Not RT-safe.
MemoryPolicyResult apply_memory_policy(std::size_t heap_prefault_bytes) noexcept;

// Touches `bytes` of the calling thread's stack so it is resident (call at task
// start, before the first cycle). Not RT-safe by intent: it is the warm-up.
void prefault_stack(std::size_t bytes) noexcept;

}  // namespace rack::rt
