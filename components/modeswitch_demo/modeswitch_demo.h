// ModeSwitchDemo: a component whose class commands each do one thing a real-time
// task must not do, so the mode-switch detector reports it (configs/modeswitch_demo.yaml
// lists the commands; rackctl send demo 21 triggers the first). Every deed is a line
// of its own in modeswitch_demo.cpp, marked `DEMO-LINE: <deed>`, so a report can be
// checked to symbolize to exactly that line.
//
// Real-time contract: deliberately NOT real-time safe in its class commands and,
// on request, in loop(). Never deploy it on a robot.
#pragma once

#include <atomic>
#include <cstddef>
#include <mutex>

#include "rack/core/data_component.h"
#include "modeswitch_demo_types.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

class ModeSwitchDemo final : public DataComponent<interfaces::ModeSwitchDemoData> {
 public:
  ModeSwitchDemo();

 protected:
  void init() override;
  HookResult loop() override;
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;
  void cleanup() override;

 private:
  void do_syscall() noexcept;
  void do_fault() noexcept;
  void do_alloc();
  void do_prioinv() noexcept;
  void do_spin(int64_t ms) noexcept;
  void do_device() noexcept;
  void do_crash() noexcept;
  void do_abort() noexcept;
  void do_loop_syscall() noexcept;
  void do_overrun() noexcept;
  void do_sleep() noexcept;

  int null_fd_ = -1;          // /dev/null
  int device_[2] = {-1, -1};  // a pipe registered as an RT device
  char* fresh_ = nullptr;     // pages that are not resident until touched
  std::size_t fresh_pages_ = 0;
  std::size_t next_page_ = 0;
  std::size_t page_ = 4096;
  std::mutex plain_mutex_;  // no priority inheritance: PRIOINV when locked in a cycle
  int* volatile null_ = nullptr;
  std::atomic<bool> loop_syscall_{false}, overrun_{false};
  int64_t cycles_ = 0;
  std::atomic<int64_t> deeds_{0};  // both tasks do deeds (commands, LOOP_SYSCALL); loop() publishes the count
};

}  // namespace rack::components
