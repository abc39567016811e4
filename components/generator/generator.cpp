#include "generator.h"
#include "generator_types.h"

#include <cmath>
#include <numbers>

namespace rack::components {

Generator::Generator()
    : DataComponent(DataTaskMode::kPeriodic),
      amplitude_(declare_float("amplitude", 1.0, {.doc = "peak value of the sine"})),
      frequency_(declare_float("frequency_hz", 0.5, {.doc = "sine frequency", .min = 0.0, .max = 1e4, .unit = "Hz"})),
      offset_(declare_float("offset", 0.0, {.doc = "added to every value"})) {}

HookResult Generator::on() {
  resets_.clear();
  counter_ = 0;
  start_ns_ = rt::monotonic_ns();
  return HookResult::kOk;
}

HookResult Generator::loop() {
  const double t = static_cast<double>(rt::monotonic_ns() - start_ns_) * 1e-9;
  interfaces::GeneratorData d;
  d.value = amplitude_.get_float() * std::sin(2.0 * std::numbers::pi * frequency_.get_float() * t) +
            offset_.get_float();
  if (uint32_t resets = 0; resets_.take(resets)) counter_ = 0;
  d.counter = ++counter_;
  publish(d, rt::host_time_ns());
  return HookResult::kOk;
}

CommandResult Generator::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kGeneratorReset) return CommandResult::kUnknown;
  if (!body.empty()) {
    reject_malformed(request, "RESET takes no body");
    return CommandResult::kHandled;
  }
  resets_.post([](uint32_t& n) { ++n; });
  reply(request, tims::msg::kOk);
  return CommandResult::kHandled;
}

}  // namespace rack::components
