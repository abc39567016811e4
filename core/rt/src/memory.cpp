#include "rack/rt/memory.h"

#include <alloca.h>
#include <link.h>
#include <malloc.h>
#include <pthread.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

namespace rack::rt {

std::string MemoryPolicyResult::describe() const {
  if (skipped_for_sanitizer) {
    return "memory NOT locked: ThreadSanitizer build: mlockall and heap/stack pre-faulting are skipped";
  }
  if (locked) {
    return "memory locked (mlockall), heap pre-faulted " + std::to_string(prefaulted_heap_bytes / 1024) + " KiB";
  }
  return std::string("memory NOT locked: mlockall failed: ") + std::strerror(lock_errno);
}

void note_sanitizer_memory_policy() noexcept {
  if constexpr (kThreadSanitizer) {
    static std::atomic<bool> said{false};
    if (said.exchange(true, std::memory_order_relaxed)) return;
    std::fprintf(stderr,
                 "rack: ThreadSanitizer build: memory is not locked (mlockall would try to make TSan's TiBs of "
                 "shadow memory resident), heap and task stacks are not pre-faulted, task stacks get %zu KiB more "
                 "for TSan's thread state; timing is not real-time\n",
                 sanitizer_stack_extra_bytes() / 1024);
  }
}

std::size_t sanitizer_stack_extra_bytes() noexcept {
  if constexpr (!kThreadSanitizer) {
    return 0;
  } else {
    // Computed once: the loaded objects' PT_TLS segments (static TLS), plus room for
    // glibc's thread descriptor and TLS surplus.
    static const std::size_t kExtra = [] {
      std::size_t tls = 0;
      dl_iterate_phdr(
          [](dl_phdr_info* info, std::size_t, void* data) {
            for (int i = 0; i < info->dlpi_phnum; ++i) {
              const auto& ph = info->dlpi_phdr[i];
              if (ph.p_type == PT_TLS) {
                *static_cast<std::size_t*>(data) += static_cast<std::size_t>(ph.p_memsz + ph.p_align);
              }
            }
            return 0;
          },
          &tls);
      return tls + 64 * 1024;
    }();
    return kExtra;
  }
}

void limit_default_thread_stack() noexcept {
  // Service threads: 1 MiB stacks, not 8 MiB each locked (memory.h).
  pthread_attr_t attr;
  if (pthread_getattr_default_np(&attr) != 0) return;
  std::size_t current = 0;
  if (pthread_attr_getstacksize(&attr, &current) == 0 && current > kServiceThreadStackBytes) {
    pthread_attr_setstacksize(&attr, kServiceThreadStackBytes);
    pthread_setattr_default_np(&attr);
  }
  pthread_attr_destroy(&attr);
}

MemoryPolicyResult apply_memory_policy(std::size_t heap_prefault_bytes) noexcept {
  MemoryPolicyResult result;
  if constexpr (kThreadSanitizer) {
    note_sanitizer_memory_policy();
    result.skipped_for_sanitizer = true;
    return result;
  }
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
  limit_default_thread_stack();
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

std::size_t unlock_file_mappings(const std::vector<std::string>& paths) noexcept {
  if (paths.empty()) return 0;
  std::size_t unlocked = 0;
  try {
    std::ifstream maps("/proc/self/maps");
    std::string line;
    while (std::getline(maps, line)) {
      // "start-end perms offset dev inode   path"
      const auto path_at = line.find('/');
      if (path_at == std::string::npos) continue;
      const std::string path = line.substr(path_at);
      if (std::find(paths.begin(), paths.end(), path) == paths.end()) continue;
      const auto dash = line.find('-');
      const auto space = line.find(' ');
      if (dash == std::string::npos || space == std::string::npos || dash > space) continue;
      const uintptr_t start = std::stoull(line.substr(0, dash), nullptr, 16);
      const uintptr_t end = std::stoull(line.substr(dash + 1, space - dash - 1), nullptr, 16);
      if (end > start && munlock(reinterpret_cast<void*>(start), end - start) == 0) unlocked += end - start;
    }
  } catch (...) {
    // /proc unreadable or a malformed line: what was unlocked so far stays so.
  }
  return unlocked;
}

void prefault_stack(std::size_t bytes) noexcept {
  if constexpr (kThreadSanitizer) return;  // the stack is mostly TSan's TLS: see memory.h
  // Touch `bytes` below the current frame. alloca keeps it on this thread's stack;
  // the empty asm keeps the compiler from dropping the writes.
  auto* area = static_cast<char*>(alloca(bytes));
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  for (std::size_t i = 0; i < bytes; i += page) area[i] = 0;
  asm volatile("" : : "r"(area) : "memory");
}

}  // namespace rack::rt
