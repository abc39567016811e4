// ChassisBase: the Chassis class's command protocol, shared by every chassis (the
// simulated one and the CAN drive), so that a pilot, a joystick or rackctl meets the
// same rules whichever drives the robot:
//
// - SET_ACTIVE_PILOT (ChassisSetActivePilot): from now on only that component (any of
//   its mailboxes) may MOVE; 0 releases the chassis. When the active pilot changes
//   the robot is stopped first (a new driver starts from standstill); the same pilot
//   set again changes nothing.
// - MOVE (ChassisMove): accepted only from the active pilot and only while ENABLED;
//   velocities must be finite and are clamped to the chassis limits (vx_max,
//   omega_max of GET_PARAMS, vy to vy_max(): 0 on a differential drive). Each
//   accepted MOVE feeds the command watchdog (last_move_ns()).
// - GET_PARAMS (no body): PARAMS reply with chassis_params().
// A malformed body is rejected (counted, ERROR reply naming what was wrong).
//
// Real-time contract: command() and every function here are RT-safe (atomics, no
// allocation, no system call); the hooks the implementation supplies must be too.
#pragma once

#include <atomic>
#include <cstdint>
#include <span>

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class ChassisBase : public DataComponent<interfaces::ChassisData> {
 public:
  struct Velocity {
    double vx = 0.0;
    double vy = 0.0;
    double omega = 0.0;
  };

 protected:
  explicit ChassisBase(DataTaskMode mode) : DataComponent(mode) {}

  // The limits GET_PARAMS answers and MOVE is clamped to. RT-safe.
  [[nodiscard]] virtual interfaces::ChassisParams chassis_params() const noexcept = 0;
  // The sideways limit (m/s); 0 (the default): a differential drive. RT-safe.
  [[nodiscard]] virtual double vy_max() const noexcept { return 0.0; }
  // The velocity the drive should now run at: an accepted MOVE (clamped) or a stop
  // because the active pilot changed (command task), handed to the data task, which
  // takes the newest with take_velocity() (false, `v` untouched: none since). RT-safe.
  void command_velocity(const Velocity& v) noexcept { velocity_.post(v); }
  [[nodiscard]] bool take_velocity(Velocity& v) noexcept { return velocity_.take(v); }

  // For on(): no active pilot, and the watchdog counts from now. RT-safe.
  void reset_pilot() noexcept;
  // The active pilot (raw component address, 0: none). RT-safe.
  [[nodiscard]] uint32_t active_pilot() const noexcept { return active_pilot_.load(std::memory_order_relaxed); }
  // When the last MOVE was accepted (or reset_pilot()), monotonic ns. RT-safe.
  [[nodiscard]] int64_t last_move_ns() const noexcept { return last_move_ns_.load(std::memory_order_relaxed); }

  // Handles MOVE, SET_ACTIVE_PILOT and GET_PARAMS; kUnknown for anything else.
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  // Written by the command task only; relaxed: the data task reads last_move_ns_ for
  // its watchdog (a stale value delays it by one cycle) and copies active_pilot_ into
  // the published sample.
  std::atomic<int64_t> last_move_ns_{0};
  std::atomic<uint32_t> active_pilot_{0};
  Handoff<Velocity> velocity_;  // command task -> data task
};

}  // namespace rack::components
