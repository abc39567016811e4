#include "odometry/odometry.h"
#include "odometry_types.h"

#include <cmath>

namespace rack::components {

using interfaces::ChassisData;

Odometry::Odometry()
    : DataComponent(DataTaskMode::kTriggered),
      // every sample (no period asked): increments must not be skipped
      chassis_(declare_input<ChassisData>("chassis", {.doc = "the Chassis to integrate"})) {}

HookResult Odometry::on() {
  odo_ = interfaces::OdometryData{};
  resets_.clear();
  return HookResult::kOk;
}

HookResult Odometry::loop() {
  const Received r = receive([&](const InputPort&) {
    const ChassisData& c = chassis_.value();
    if (uint32_t resets = 0; resets_.take(resets)) {
      odo_.x = odo_.y = odo_.phi = odo_.distance = 0.0;
      odo_.resets += resets;
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
    publish(odo_, chassis_.time_ns());
  });
  return r.failed ? HookResult::kError : HookResult::kOk;
}

CommandResult Odometry::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kOdometryReset) return CommandResult::kUnknown;
  if (!body.empty()) {
    reject_malformed(request, "RESET takes no body");
    return CommandResult::kHandled;
  }
  resets_.post([](uint32_t& n) { ++n; });
  reply(request, tims::msg::kOk);
  return CommandResult::kHandled;
}

}  // namespace rack::components
