#include "probe.h"

#include <cmath>
#include <stdexcept>

namespace rack::components {

Probe::Probe()
    : DataComponent(DataTaskMode::kPeriodic),
      fail_init_(declare_bool("fail_init", false, {.doc = "init() throws", .init_only = true})),
      init_delay_ms_(declare_float("init_delay_ms", 0.0,
                                   {.doc = "init() takes this long (a slow start-up: a large map, a device)",
                                    .min = 0,
                                    .max = 600000,
                                    .init_only = true,
                                    .unit = "ms"})),
      fail_on_(declare_bool("fail_on", false, {.doc = "on() returns an error"})),
      throw_on_(declare_bool("throw_on", false, {.doc = "on() throws"})),
      fail_loop_(declare_bool("fail_loop", false, {.doc = "loop() returns an error"})),
      throw_loop_(declare_bool("throw_loop", false, {.doc = "loop() throws"})),
      on_delay_ms_(
          declare_float("on_delay_ms", 0.0, {.doc = "on() takes this long", .min = 0, .max = 60000, .unit = "ms"})),
      label_(declare_string("label", "probe", {.doc = "free text (string parameter tests)"})) {}

void Probe::init() {
  // One uninterruptible wait, as a library call that does not return soon would be.
  rt::sleep_for(std::llround(init_delay_ms_.get_float() * 1e6));
  if (fail_init_.get_bool()) throw std::runtime_error("fail_init is set");
}

HookResult Probe::on() {
  on_calls_.fetch_add(1, std::memory_order_relaxed);
  rt::sleep_for(std::llround(on_delay_ms_.get_float() * 1e6));
  if (throw_on_.get_bool()) throw std::runtime_error("throw_on is set");
  return fail_on_.get_bool() ? HookResult::kError : HookResult::kOk;
}

void Probe::off() { off_calls_.fetch_add(1, std::memory_order_relaxed); }

HookResult Probe::loop() {
  loops_.fetch_add(1, std::memory_order_relaxed);
  if (throw_loop_.get_bool()) throw std::runtime_error("throw_loop is set");
  interfaces::ProbeData d;
  d.loops = loops_.load(std::memory_order_relaxed);
  d.on_calls = on_calls_.load(std::memory_order_relaxed);
  d.off_calls = off_calls_.load(std::memory_order_relaxed);
  publish(d, rt::host_time_ns());
  return fail_loop_.get_bool() ? HookResult::kError : HookResult::kOk;
}

CommandResult Probe::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type == interfaces::kProbeThrow) throw std::runtime_error("kProbeThrow");
  if (request.type != interfaces::kProbeEcho) return CommandResult::kUnknown;
  if (body.size() != 8) {
    reject_malformed(request, "ECHO takes an 8-byte body");
    return CommandResult::kHandled;
  }
  const tims::ConstBuffer part{body.data(), body.size()};
  reply(request, tims::msg::kOk, std::span<const tims::ConstBuffer>(&part, 1));
  return CommandResult::kHandled;
}

}  // namespace rack::components
