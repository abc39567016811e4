#include "odometry/odometry.h"

#include <cmath>

namespace rack::components {

using interfaces::ChassisData;

Odometry::Odometry()
    : DataComponent(DataTaskMode::kTriggered), chassis_(declare_component_ref("chassis", "the Chassis to integrate")) {
  use_input_mailbox(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(ChassisData) + 64);
}

HookResult Odometry::on() {
  odo_ = interfaces::OdometryData{};
  resets_applied_ = reset_requests_.load(std::memory_order_relaxed);
  const tims::Address chassis = resolved(chassis_);
  if (switch_on(chassis) != HookResult::kOk) return HookResult::kError;  // cascading ON
  return subscribe(chassis, 0);                                          // every sample: increments must not be skipped
}

void Odometry::off() { unsubscribe(resolved(chassis_)); }

HookResult Odometry::loop() {
  bool got = false;
  for (;;) {
    wire::SampleHeader sh;
    ChassisData c;
    const Input in = next_sample(sh, c);
    if (in == Input::kNone) break;
    if (in == Input::kError) return HookResult::kError;  // the chassis left ENABLED: re-subscribe on retry
    got = true;
    const uint32_t requested = reset_requests_.load(std::memory_order_relaxed);
    if (requested != resets_applied_) {
      odo_.x = odo_.y = odo_.phi = odo_.distance = 0.0;
      odo_.resets += requested - resets_applied_;
      resets_applied_ = requested;
    }
    if (std::isfinite(c.delta_x) && std::isfinite(c.delta_y) && std::isfinite(c.delta_phi)) {
      const Pose2d pose = compose(Pose2d{odo_.x, odo_.y, odo_.phi}, Pose2d{c.delta_x, c.delta_y, c.delta_phi});
      odo_.x = pose.x;
      odo_.y = pose.y;
      odo_.phi = pose.phi;
      odo_.distance += std::hypot(c.delta_x, c.delta_y);
    }
    odo_.vx = c.vx;
    odo_.omega = c.omega;
    publish(odo_, sh.time_ns);
  }
  // Nothing usable: an error once the chassis has been silent for data_timeout.
  return got || !input_silent() ? HookResult::kOk : HookResult::kError;
}

CommandResult Odometry::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kOdometryReset) return CommandResult::kUnknown;
  if (!body.empty()) {
    reject_malformed(request, "RESET takes no body");
    return CommandResult::kHandled;
  }
  reset_requests_.fetch_add(1, std::memory_order_relaxed);
  reply(request, tims::msg::kOk);
  return CommandResult::kHandled;
}

}  // namespace rack::components
