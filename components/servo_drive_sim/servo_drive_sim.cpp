#include "servo_drive_sim/servo_drive_sim.h"

#include <algorithm>
#include <cmath>

namespace rack::components {

using interfaces::ServoDriveData;

ServoDriveSim::ServoDriveSim()
    : DataComponent(DataTaskMode::kPeriodic),
      initial_position_(declare_float("initial_position", 0.0, {.doc = "unit, where the axis starts (homed)"})),
      max_velocity_(declare_float("max_velocity", 1.0, {.doc = "unit/s, also the default move speed", .min = 1e-6})),
      acceleration_(declare_float("acceleration", 4.0, {.doc = "unit/s^2", .min = 1e-6})),
      position_min_(declare_float("position_min", -1.0, {.doc = "unit, lower limit"})),
      position_max_(declare_float("position_max", 1.0, {.doc = "unit, upper limit"})),
      home_position_(
          declare_float("home_position", 0.0, {.doc = "unit, the position HOME assigns to where the axis is"})) {}

HookResult ServoDriveSim::on() {
  if (last_ns_ == 0) {  // first ON: start where the parameter says; later ONs keep the axis where it is
    position_ = std::clamp(initial_position_.get_float(), position_min_.get_float(), position_max_.get_float());
    target_ = position_;
  }
  velocity_ = 0.0;
  moving_ = false;
  velocity_mode_ = false;
  last_ns_ = rt::monotonic_ns();
  position_reading_.store(position_, std::memory_order_relaxed);
  return HookResult::kOk;
}

CommandResult ServoDriveSim::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  switch (request.type) {
    case interfaces::kServoDriveHome:
      home_.post(true);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    case interfaces::kServoDriveMovePos: {
      interfaces::ServoDriveMovePos m;
      if (!wire::read_payload(body, tims::body_is_native(request), m) || !std::isfinite(m.position) ||
          !std::isfinite(m.velocity) || m.velocity < 0.0) {
        reject_malformed(request, "MOVE_POS: body must be a ServoDriveMovePos with finite values, velocity >= 0");
        return CommandResult::kHandled;
      }
      if (m.position < position_min_.get_float() - 1e-9 || m.position > position_max_.get_float() + 1e-9) {
        reply_error(request, "MOVE_POS: target outside [position_min, position_max]");
        return CommandResult::kHandled;
      }
      Move move;
      move.target = m.position;
      move.velocity = m.velocity > 0.0 ? std::min(m.velocity, max_velocity_.get_float()) : max_velocity_.get_float();
      move.requester = request.src;
      move_.post(move);
      moves_.fetch_add(1, std::memory_order_relaxed);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    case interfaces::kServoDriveMoveVel: {
      interfaces::ServoDriveMoveVel m;
      if (!wire::read_payload(body, tims::body_is_native(request), m) || !std::isfinite(m.velocity)) {
        reject_malformed(request, "MOVE_VEL: body must be a ServoDriveMoveVel with a finite velocity");
        return CommandResult::kHandled;
      }
      Move move;
      move.vel_command = std::clamp(m.velocity, -max_velocity_.get_float(), max_velocity_.get_float());
      move.is_velocity = true;
      move_.post(move);
      moves_.fetch_add(1, std::memory_order_relaxed);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    default: return CommandResult::kUnknown;
  }
}

HookResult ServoDriveSim::loop() {
  const int64_t now = rt::monotonic_ns();
  const double dt = std::clamp(static_cast<double>(now - last_ns_) * 1e-9, 0.0, 0.5);
  last_ns_ = now;
  const double lo = position_min_.get_float(), hi = position_max_.get_float();
  if (bool home = false; home_.take(home)) {
    position_ = home_position_.get_float();
    target_ = position_;
    velocity_ = 0.0;
    moving_ = false;
  }
  if (Move move; move_.take(move)) {
    velocity_mode_ = move.is_velocity;
    if (velocity_mode_) {
      const double v = move.vel_command;
      speed_ = std::fabs(v);
      target_ = v > 0.0 ? hi : v < 0.0 ? lo : position_;
    } else {
      target_ = move.target;
      speed_ = move.velocity;
    }
    notify_ = move.requester;
    moving_ = true;
  }
  // Trapezoidal profile towards target_: accelerate to speed_, brake in time to stop there.
  const double acc = acceleration_.get_float();
  const double to_go = target_ - position_;
  const double dir = to_go > 0.0 ? 1.0 : -1.0;
  const double brake_speed = std::sqrt(2.0 * acc * std::fabs(to_go));
  const double want = dir * std::min(speed_, brake_speed);
  const double dv = std::clamp(want - velocity_, -acc * dt, acc * dt);
  velocity_ += dv;
  double next = position_ + velocity_ * dt;
  // Arrived (or would pass the target within this step): stop exactly there.
  if (std::fabs(to_go) < 1e-6 || (to_go > 0.0) != (target_ - next > 0.0)) {
    next = target_;
    velocity_ = 0.0;
  }
  position_ = std::clamp(next, lo, hi);
  const bool reached = std::fabs(target_ - position_) < 1e-6 && velocity_ == 0.0;
  position_reading_.store(position_, std::memory_order_relaxed);
  if (reached && moving_) {
    moving_ = false;
    ++reached_;
    if (notify_ != 0) {
      const double at = position_;
      const tims::ConstBuffer part = tims::buffer_of(at);
      (void)data_endpoint().send(tims::Address(notify_), interfaces::kServoDrivePositionReached,
                                 std::span<const tims::ConstBuffer>(&part, 1));
    }
  }
  out_.position = position_;
  out_.velocity = velocity_;
  out_.target = target_;
  out_.statusword = reached ? 0x0437 : 0x0037;  // CiA 402 operation enabled (+ bit 10 target reached)
  out_.target_reached = reached ? 1 : 0;
  out_.homed = 1;
  out_.moves = moves_.load(std::memory_order_relaxed);
  out_.reached = reached_;
  publish(out_, rt::host_time_ns());
  return HookResult::kOk;
}

}  // namespace rack::components
