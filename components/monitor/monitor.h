// Monitor: a consumer (demo). Its declared input `source` (a Generator, asked for a
// sample every source_period_ms) is switched on and subscribed to by the framework;
// it publishes what it saw: samples received, gaps, latency.
#pragma once

#include "rack/core/data_component.h"
#include "monitor_types.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

class Monitor final : public DataComponent<interfaces::MonitorData> {
 public:
  Monitor();

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, triggered by the input mailbox

 private:
  InputOf<interfaces::GeneratorData>& source_;
  interfaces::MonitorData stats_{};
  uint64_t last_sequence_ = 0;
  uint64_t step_ = 0;
  bool have_last_ = false;
};

}  // namespace rack::components
