// The replacement allocator of the no-allocation test binaries: operator new/delete
// and glibc's malloc family, forwarding to glibc's __libc_* entry points, each
// reporting to two hooks that the including binary defines (once, in one file):
//
//   void rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall, std::size_t) noexcept;
//   void rack_test_note_free() noexcept;
//
// Each binary decides what counts (every thread, or only the measuring thread) and
// whether to forward to the mode-switch detector's hook, as a program that replaces
// the allocator must to keep ALLOC detection working (core/rt/src/alloc_hooks.cpp is
// the production counterpart, linked into rackd as rack::rt_hooks).
//
// Include from exactly one translation unit of a test binary: the definitions are
// global replacements. Not for production code.
#pragma once

#include <cerrno>
#include <cstddef>
#include <new>

#include "rack/rt/modeswitch.h"

void rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall call, std::size_t size) noexcept;
void rack_test_note_free() noexcept;

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* ptr, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* ptr);

void* malloc(std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kMalloc, size);
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kCalloc, count * size);
  return __libc_calloc(count, size);
}
void* realloc(void* ptr, std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kRealloc, size);
  return __libc_realloc(ptr, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kAlignedAlloc, size);
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kAlignedAlloc, size);
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kAlignedAlloc, size);
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* ptr) noexcept {
  if (ptr != nullptr) rack_test_note_free();
  __libc_free(ptr);
}
}  // extern "C"

namespace rack_test_counting_allocator {
inline void* counted_new(std::size_t size) {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kNew, size);
  if (void* p = __libc_malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
inline void* counted_new_aligned(std::size_t size, std::align_val_t align) {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kNew, size);
  if (void* p = __libc_memalign(static_cast<std::size_t>(align), size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
inline void* counted_new_nothrow(std::size_t size) noexcept {
  rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall::kNew, size);
  return __libc_malloc(size == 0 ? 1 : size);
}
}  // namespace rack_test_counting_allocator

void* operator new(std::size_t size) { return rack_test_counting_allocator::counted_new(size); }
void* operator new[](std::size_t size) { return rack_test_counting_allocator::counted_new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  return rack_test_counting_allocator::counted_new_nothrow(size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return rack_test_counting_allocator::counted_new_nothrow(size);
}
void* operator new(std::size_t size, std::align_val_t align) {
  return rack_test_counting_allocator::counted_new_aligned(size, align);
}
void* operator new[](std::size_t size, std::align_val_t align) {
  return rack_test_counting_allocator::counted_new_aligned(size, align);
}
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }
