// Generator: a periodic producer (demo). Publishes amplitude * sin(2 pi f t) + offset
// and a counter every period.
#pragma once

#include "rack/core/data_component.h"
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
  std::atomic<int64_t> counter_{0};  // loop() writes; RESET (command task) zeroes
  int64_t start_ns_ = 0;
};

}  // namespace rack::components
