// Generator: a periodic producer (demo). Publishes amplitude * sin(2 pi f t) + offset
// and a counter every period.
#pragma once

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/interfaces/demo.h"

namespace rack::components {

class Generator final : public DataComponent<interfaces::GeneratorData> {
 public:
  Generator();

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  Parameter& amplitude_;
  Parameter& frequency_;
  Parameter& offset_;
  Handoff<uint32_t> resets_;  // RESETs asked for (command task); loop() zeroes the counter
  int64_t counter_ = 0;       // data task (on() zeroes it while the data task is idle)
  int64_t start_ns_ = 0;
};

}  // namespace rack::components
