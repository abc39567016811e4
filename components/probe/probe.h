// Probe: a test component whose hooks fail or throw on demand (parameters, settable
// at run time with SET_PARAM), so every life-cycle transition can be driven from
// outside (STYLE.md 2). Publishes how often each hook ran.
#pragma once

#include "rack/core/data_component.h"
#include "probe_types.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

class Probe final : public DataComponent<interfaces::ProbeData> {
 public:
  Probe();

 protected:
  void init() override;
  HookResult on() override;
  void off() override;
  HookResult loop() override;
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  Parameter& fail_init_;
  Parameter& init_delay_ms_;
  Parameter& fail_on_;
  Parameter& throw_on_;
  Parameter& fail_loop_;
  Parameter& throw_loop_;
  Parameter& on_delay_ms_;
  Parameter& label_;
  std::atomic<int64_t> loops_{0}, on_calls_{0}, off_calls_{0};
};

}  // namespace rack::components
