// The program's pthread_create (rack/rt/thread_birth.h): with CPU partitioning, every
// thread that is not one of the executor's own is born on the housekeeping CPUs with
// SCHED_OTHER, whichever library or plug-in creates it and from whichever thread.
// Linked into the program (the OBJECT library rack::rt_hooks, beside alloc_hooks.cpp)
// and exported (-Wl,--export-dynamic-symbol=pthread_create, core/rt/CMakeLists.txt):
// the dynamic linker then binds this definition for libstdc++, libgomp, libtbb, GLib and
// libraries that plug-ins bring with dlopen(), before glibc's own.
//
// Real-time contract: not RT-safe (creating a thread never is).
#include <dlfcn.h>
#include <pthread.h>

#include <cerrno>

#include "rack/rt/thread_birth.h"

using rack::rt::thread_birth::detail::CreateFn;

namespace {

// glibc's pthread_create (the default version), found once. Resolved at load time by the
// constructor below; the lazy path covers a library constructor that creates a thread
// before it runs.
CreateFn g_real_create = nullptr;

CreateFn real_create() noexcept {
  CreateFn f = __atomic_load_n(&g_real_create, __ATOMIC_ACQUIRE);
  if (f == nullptr) {
    f = reinterpret_cast<CreateFn>(dlsym(RTLD_NEXT, "pthread_create"));
    __atomic_store_n(&g_real_create, f, __ATOMIC_RELEASE);
  }
  return f;
}

__attribute__((constructor)) void resolve_real_create() { (void)real_create(); }

}  // namespace

extern "C" {

int pthread_create(pthread_t* thread, const pthread_attr_t* attr, void* (*start)(void*), void* arg) noexcept {
  return rack::rt::thread_birth::detail::create(real_create(), thread, attr, start, arg);
}

// thread_birth::interposed() compares this with what dlsym(RTLD_DEFAULT) finds.
void* rack_rt_pthread_create_hook() { return reinterpret_cast<void*>(&pthread_create); }

}  // extern "C"
