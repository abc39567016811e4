#include "rack/rt/memory.h"

#include <alloca.h>
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace rack::rt {

std::string MemoryPolicyResult::describe() const {
  if (locked) {
    return "memory locked (mlockall), heap pre-faulted " +
           std::to_string(prefaulted_heap_bytes / 1024) + " KiB";
  }
  return std::string("memory NOT locked: mlockall failed: ") + std::strerror(lock_errno);
}

MemoryPolicyResult apply_memory_policy(std::size_t heap_prefault_bytes) noexcept {
  MemoryPolicyResult result;
  // Never give heap back to the kernel, never serve malloc from fresh mmaps: both
  // would be system calls and page faults inside whatever RT task frees or allocates.
  mallopt(M_TRIM_THRESHOLD, -1);
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_ARENA_MAX, 1);  // one arena: pre-faulted memory is where every thread allocates

  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    result.locked = true;
  } else {
    result.lock_errno = errno;
  }
  if (heap_prefault_bytes > 0) {
    // Grow the heap once and touch every page; with trimming off the pages stay.
    auto* block = static_cast<volatile char*>(std::malloc(heap_prefault_bytes));
    if (block != nullptr) {
      const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
      for (std::size_t i = 0; i < heap_prefault_bytes; i += page) block[i] = 0;
      std::free(const_cast<char*>(block));
      result.prefaulted_heap_bytes = heap_prefault_bytes;
    }
  }
  return result;
}

void prefault_stack(std::size_t bytes) noexcept {
  // Touch `bytes` below the current frame. alloca keeps it on this thread's stack;
  // the empty asm keeps the compiler from dropping the writes.
  auto* area = static_cast<char*>(alloca(bytes));
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  for (std::size_t i = 0; i < bytes; i += page) area[i] = 0;
  asm volatile("" : : "r"(area) : "memory");
}

}  // namespace rack::rt
