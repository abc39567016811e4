#include "modeswitch_demo.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

namespace rack::components {

namespace msg = tims::msg;

ModeSwitchDemo::ModeSwitchDemo() : DataComponent(DataTaskMode::kPeriodic) {}

void ModeSwitchDemo::init() {
  null_fd_ = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null_fd_ < 0) throw std::runtime_error(std::string("open /dev/null: ") + std::strerror(errno));
  if (pipe2(device_, O_CLOEXEC | O_NONBLOCK) != 0) {
    throw std::runtime_error(std::string("pipe2: ") + std::strerror(errno));
  }
  register_rt_device(device_[0]);
  register_rt_device(device_[1]);
  // Pages for FAULT: mapped (and, under mlockall(MCL_FUTURE), populated and locked),
  // then unlocked and dropped, so each first touch is a page fault.
  page_ = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  fresh_pages_ = 4096;
  void* area = mmap(nullptr, fresh_pages_ * page_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (area == MAP_FAILED) throw std::runtime_error(std::string("mmap: ") + std::strerror(errno));
  fresh_ = static_cast<char*>(area);
  munlock(fresh_, fresh_pages_ * page_);
  madvise(fresh_, fresh_pages_ * page_, MADV_DONTNEED);
}

void ModeSwitchDemo::cleanup() {
  if (null_fd_ >= 0) ::close(null_fd_);
  for (int& fd : device_) {
    if (fd < 0) continue;
    unregister_rt_device(fd);
    ::close(fd);
    fd = -1;
  }
  if (fresh_ != nullptr) munmap(fresh_, fresh_pages_ * page_);
}

// Each deed is one marked line; noinline keeps it a frame of its own in backtraces.
__attribute__((noinline)) void ModeSwitchDemo::do_syscall() noexcept {
  const ssize_t n = ::write(null_fd_, "mode switch\n", 12);  // DEMO-LINE: SYSCALL
  deeds_.fetch_add(n > 0 ? 1 : 0, std::memory_order_relaxed);
}

__attribute__((noinline)) void ModeSwitchDemo::do_fault() noexcept {
  char* page = fresh_ + (next_page_++ % fresh_pages_) * page_;
  *static_cast<volatile char*>(page) = 1;  // DEMO-LINE: FAULT
  deeds_.fetch_add(1, std::memory_order_relaxed);
}

namespace {
// Keeps the compiler from eliding the new/delete pair below (C++ allows it).
char* volatile g_escape = nullptr;
}  // namespace

__attribute__((noinline)) void ModeSwitchDemo::do_alloc() {
  auto* block = new char[256];  // DEMO-LINE: ALLOC
  g_escape = block;
  deeds_.fetch_add(1, std::memory_order_relaxed);
  delete[] g_escape;
}

__attribute__((noinline)) void ModeSwitchDemo::do_prioinv() noexcept {
  std::lock_guard lock(plain_mutex_);  // DEMO-LINE: PRIOINV
  deeds_.fetch_add(1, std::memory_order_relaxed);
}

__attribute__((noinline)) void ModeSwitchDemo::do_spin(int64_t ms) noexcept {
  const int64_t until = rt::monotonic_ns() + ms * rt::kNsPerMs;
  while (rt::monotonic_ns() < until) {  // DEMO-LINE: SPIN
  }
  deeds_.fetch_add(1, std::memory_order_relaxed);
}

__attribute__((noinline)) void ModeSwitchDemo::do_device() noexcept {
  char byte = 1;
  if (::write(device_[1], &byte, 1) == 1) deeds_.fetch_add(1, std::memory_order_relaxed);  // registered: allowed
  (void)!::read(device_[0], &byte, 1);
}

__attribute__((noinline)) void ModeSwitchDemo::do_crash() noexcept {
  *null_ = 42;  // DEMO-LINE: CRASH
  deeds_.fetch_add(1, std::memory_order_relaxed);
}

__attribute__((noinline)) void ModeSwitchDemo::do_abort() noexcept {
  std::abort();  // DEMO-LINE: ABORT
}

__attribute__((noinline)) void ModeSwitchDemo::do_loop_syscall() noexcept {
  const ssize_t n = ::write(null_fd_, "loop\n", 5);  // DEMO-LINE: LOOP_SYSCALL
  deeds_.fetch_add(n > 0 ? 1 : 0, std::memory_order_relaxed);
}

__attribute__((noinline)) void ModeSwitchDemo::do_overrun() noexcept {
  do_spin(30 * period_ns() / rt::kNsPerMs + 1);  // DEMO-LINE: OVERRUN
}

// clock_nanosleep is on the allow-list, but a sleep that bypasses the framework is
// a voluntary context switch without a framework wait: RUSAGE sees it.
__attribute__((noinline)) void ModeSwitchDemo::do_sleep() noexcept {
  ::usleep(2000);  // DEMO-LINE: SLEEP
  deeds_.fetch_add(1, std::memory_order_relaxed);
}

HookResult ModeSwitchDemo::loop() {
  ++cycles_;
  if (loop_syscall_.exchange(false, std::memory_order_relaxed)) do_loop_syscall();
  if (overrun_.exchange(false, std::memory_order_relaxed)) do_overrun();
  interfaces::ModeSwitchDemoData d;
  d.cycles = cycles_;
  d.deeds = deeds_.load(std::memory_order_relaxed);
  publish(d, rt::host_time_ns());
  return HookResult::kOk;
}

CommandResult ModeSwitchDemo::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  namespace i = interfaces;
  int64_t spin_ms = 300;
  switch (request.type) {
    case i::kDemoSyscall: do_syscall(); break;
    case i::kDemoFault: do_fault(); break;
    case i::kDemoAlloc: do_alloc(); break;
    case i::kDemoPrioInv: do_prioinv(); break;
    case i::kDemoSpin:
      if (body.size() == sizeof spin_ms) std::memcpy(&spin_ms, body.data(), sizeof spin_ms);
      else if (!body.empty()) {
        reject_malformed(request, "SPIN takes no body or an 8-byte millisecond count");
        return CommandResult::kHandled;
      }
      if (spin_ms < 0 || spin_ms > 10'000) {
        reject_malformed(request, "SPIN: 0..10000 ms");
        return CommandResult::kHandled;
      }
      do_spin(spin_ms);
      break;
    case i::kDemoOverrun: overrun_.store(true, std::memory_order_relaxed); break;
    case i::kDemoLoopSyscall: loop_syscall_.store(true, std::memory_order_relaxed); break;
    case i::kDemoDevice: do_device(); break;
    case i::kDemoSleep: do_sleep(); break;
    case i::kDemoCrash: do_crash(); break;
    case i::kDemoAbort: do_abort(); break;
    default: return CommandResult::kUnknown;
  }
  reply(request, msg::kOk);
  return CommandResult::kHandled;
}

}  // namespace rack::components
