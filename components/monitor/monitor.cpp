#include "monitor.h"

namespace rack::components {

using interfaces::GeneratorData;

Monitor::Monitor()
    : DataComponent(DataTaskMode::kTriggered),
      source_(declare_component_ref("source", "the Generator to watch")),
      period_ms_(declare_float("period_ms", 0.0,
                               {.doc = "requested sample period (0: every sample)", .min = 0.0, .max = 3.6e6})) {
  use_input_mailbox(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(GeneratorData) + 128);
}

HookResult Monitor::on() {
  stats_ = interfaces::MonitorData{};
  have_last_ = false;
  step_ = 0;
  const tims::Address source = resolved(source_);
  if (switch_on(source) != HookResult::kOk) return HookResult::kError;  // cascading ON
  const auto period = static_cast<int64_t>(period_ms_.get_float() * 1e6);
  return subscribe(source, period, &stats_.real_period_ns);
}

void Monitor::off() { unsubscribe(resolved(source_)); }

HookResult Monitor::loop() {
  bool got = false;
  for (;;) {
    wire::SampleHeader sh;
    GeneratorData d;
    const Input in = next_sample(sh, d);  // not a Generator sample: counted, skipped
    if (in == Input::kNone) break;
    if (in == Input::kError) return HookResult::kError;  // the source left ENABLED: re-subscribe later
    got = true;
    ++stats_.received;
    if (have_last_ && sh.sequence > last_sequence_) {
      const uint64_t step = sh.sequence - last_sequence_;
      if (step_ == 0 || step < step_) step_ = step;
      if (step > step_) stats_.gaps += step / step_ - 1;
    }
    have_last_ = true;
    last_sequence_ = sh.sequence;
    stats_.source_sequence = sh.sequence;
    stats_.last_value = d.value;
    stats_.latency_ns = rt::host_time_ns() - sh.time_ns;
    if (stats_.latency_ns > stats_.latency_max_ns) stats_.latency_max_ns = stats_.latency_ns;
  }
  if (!got) {  // nothing usable: an error once the source has been silent for data_timeout
    return input_silent() ? HookResult::kError : HookResult::kOk;
  }
  publish(stats_, rt::host_time_ns());
  return HookResult::kOk;
}

}  // namespace rack::components
