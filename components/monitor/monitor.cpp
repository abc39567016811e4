#include "monitor.h"

namespace rack::components {

using interfaces::GeneratorData;

Monitor::Monitor()
    : DataComponent(DataTaskMode::kTriggered),
      source_(declare_input<GeneratorData>(
          "source", {.doc = "the Generator to watch", .ask_period = true, .old_period_name = "period_ms"})) {}

HookResult Monitor::on() {
  stats_ = interfaces::MonitorData{};
  stats_.real_period_ns = source_.granted_period_ns();  // subscribed before on()
  have_last_ = false;
  step_ = 0;
  return HookResult::kOk;
}

HookResult Monitor::loop() {
  const Received r = receive([&](const InputPort&) {
    const wire::SampleHeader& sh = source_.sample_header();
    ++stats_.received;
    if (have_last_ && sh.sequence > last_sequence_) {
      const uint64_t step = sh.sequence - last_sequence_;
      if (step_ == 0 || step < step_) step_ = step;
      if (step > step_) stats_.gaps += step / step_ - 1;
    }
    have_last_ = true;
    last_sequence_ = sh.sequence;
    stats_.source_sequence = sh.sequence;
    stats_.last_value = source_.value().value;
    stats_.latency_ns = rt::host_time_ns() - sh.time_ns;
    if (stats_.latency_ns > stats_.latency_max_ns) stats_.latency_max_ns = stats_.latency_ns;
  });
  if (r.failed) return HookResult::kError;
  if (r.samples > 0) publish(stats_, rt::host_time_ns());
  return HookResult::kOk;
}

}  // namespace rack::components
