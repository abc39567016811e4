// Monitor: a consumer (demo). Switches on its source (cascading ON), subscribes with
// getContData, and publishes what it saw: samples received, gaps, latency.
#pragma once

#include "rack/core/data_component.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

class Monitor final : public DataComponent<interfaces::MonitorData> {
 public:
  Monitor();

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT, triggered by the input mailbox

 private:
  Parameter& source_;
  Parameter& period_ms_;
  interfaces::MonitorData stats_{};
  uint64_t last_sequence_ = 0;
  uint64_t step_ = 0;
  bool have_last_ = false;
};

}  // namespace rack::components
