// Interposers for ALLOC and PRIOINV detection: the malloc family, every operator
// new/delete and pthread_mutex_lock. Linked into the program (the OBJECT library
// rack::rt_hooks), never into a library: a definition in the executable is the one
// the dynamic linker binds for libstdc++, LCM and plug-ins too.
//
// Each call checks one thread-local flag (inside modeswitch::detail) and forwards to
// glibc's own entry points (__libc_malloc & co., exported for exactly this purpose),
// so there is no dlsym and no recursion on the allocation path.
//
// A program that replaces the allocator itself (tests/unit/no_alloc_test.cpp counts
// allocations) does not link this object; it calls detail::on_heap_call() from its
// own replacements to keep ALLOC detection.
//
// Real-time contract: as RT-safe as glibc's malloc (which is not): the added check
// is a thread-local load.
#include <dlfcn.h>
#include <pthread.h>

#include <cerrno>
#include <cstddef>
#include <new>

#include "rack/rt/modeswitch.h"

using rack::rt::modeswitch::detail::HeapCall;
using rack::rt::modeswitch::detail::on_heap_call;

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* ptr, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* ptr);

// Found by modeswitch::start() (weak reference): the interposers are linked.
void rack_rt_hooks_linked() {}

void* malloc(std::size_t size) noexcept {
  on_heap_call(HeapCall::kMalloc, size);
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  on_heap_call(HeapCall::kCalloc, count * size);
  return __libc_calloc(count, size);
}
void* realloc(void* ptr, std::size_t size) noexcept {
  on_heap_call(HeapCall::kRealloc, size);
  return __libc_realloc(ptr, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  on_heap_call(HeapCall::kAlignedAlloc, size);
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  on_heap_call(HeapCall::kAlignedAlloc, size);
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  on_heap_call(HeapCall::kAlignedAlloc, size);
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* ptr) noexcept {
  if (ptr == nullptr) return;
  on_heap_call(HeapCall::kFree, 0);
  __libc_free(ptr);
}

// The real pthread_mutex_lock, found once. Resolved at load time by the constructor
// below (outside any RT task); the lazy path covers calls made before it runs.
using LockFn = int (*)(pthread_mutex_t*);
static LockFn g_real_lock = nullptr;
static LockFn real_lock() noexcept {
  LockFn f = __atomic_load_n(&g_real_lock, __ATOMIC_ACQUIRE);
  if (f == nullptr) {
    f = reinterpret_cast<LockFn>(dlsym(RTLD_NEXT, "pthread_mutex_lock"));
    __atomic_store_n(&g_real_lock, f, __ATOMIC_RELEASE);
  }
  return f;
}
__attribute__((constructor)) static void resolve_real_lock() { (void)real_lock(); }

int pthread_mutex_lock(pthread_mutex_t* mutex) noexcept {
  const int rc = rack::rt::modeswitch::detail::checked_mutex_lock(mutex, real_lock());
  // Not a tail call: the detector skips a fixed number of frames (this one included).
  asm volatile("" ::: "memory");
  return rc;
}
}  // extern "C"

namespace {
void* checked_new(std::size_t size) {
  on_heap_call(HeapCall::kNew, size);
  if (void* p = __libc_malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* checked_new_aligned(std::size_t size, std::align_val_t align) {
  on_heap_call(HeapCall::kNew, size);
  if (void* p = __libc_memalign(static_cast<std::size_t>(align), size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void checked_delete(void* p) noexcept {
  if (p == nullptr) return;
  on_heap_call(HeapCall::kDelete, 0);
  __libc_free(p);
}
}  // namespace

void* operator new(std::size_t size) { return checked_new(size); }
void* operator new[](std::size_t size) { return checked_new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  on_heap_call(HeapCall::kNew, size);
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  on_heap_call(HeapCall::kNew, size);
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new(std::size_t size, std::align_val_t align) { return checked_new_aligned(size, align); }
void* operator new[](std::size_t size, std::align_val_t align) { return checked_new_aligned(size, align); }
void* operator new(std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {
  on_heap_call(HeapCall::kNew, size);
  return __libc_memalign(static_cast<std::size_t>(align), size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, std::align_val_t align, const std::nothrow_t&) noexcept {
  on_heap_call(HeapCall::kNew, size);
  return __libc_memalign(static_cast<std::size_t>(align), size == 0 ? 1 : size);
}
void operator delete(void* p) noexcept { checked_delete(p); }
void operator delete[](void* p) noexcept { checked_delete(p); }
void operator delete(void* p, std::size_t) noexcept { checked_delete(p); }
void operator delete[](void* p, std::size_t) noexcept { checked_delete(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { checked_delete(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { checked_delete(p); }
void operator delete(void* p, std::align_val_t) noexcept { checked_delete(p); }
void operator delete[](void* p, std::align_val_t) noexcept { checked_delete(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { checked_delete(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { checked_delete(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { checked_delete(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { checked_delete(p); }
