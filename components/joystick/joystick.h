// Joystick (class Joystick): a game controller through the Linux joystick API
// (/dev/input/jsN, struct js_event), and optionally a pilot that drives a chassis.
//
// Publishes JoystickData every cycle: axes scaled to [-1, 1], buttons as a bit mask,
// counters. With `chassis` set it also drives that chassis: on() switches the chassis
// on (cascading ON), makes itself the active pilot and reads the chassis limits;
// loop() sends MOVE every cycle (which also keeps the chassis watchdog fed):
//   vx = -axis[axis_forward] * vx_max * speed_scale,  omega = -axis[axis_turn] * omega_max
// (pushing the stick forward/left reports negative values on Linux), zero inside
// `deadband`, and zero unless the dead-man button is held (deadman_button >= 0).
// off() stops the robot and releases the chassis.
//
// With `obstacles` set (a Scan2D or Ladar component: a declared input, switched on and
// subscribed before on()) it limits forward speed by the free distance ahead in the
// robot's corridor (the chassis outline plus its safety margin): full speed at
// `slow_distance` or more, zero at the outline. No scan for silence_ms allows no
// forward motion (fail safe); the source leaving ENABLED puts the joystick in ERROR
// (and stops the robot).
//
// Bad input: short events, unknown event types and out-of-range axis/button numbers
// are counted (bad_events) and ignored. A device that disappears (unplugged: ENODEV,
// EOF on a FIFO) puts the component in ERROR; on() retries and reopens it.
//
// Data task: periodic (e.g. 20 ms). Real-time contract: loop() does non-blocking
// read() on the device and one bounded MOVE call; on() opens the device.
#pragma once

#include <array>

#include "rack/core/data_component.h"
#include "joystick_types.h"
#include "js_events.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Joystick final : public DataComponent<interfaces::JoystickData> {
 public:
  Joystick();
  ~Joystick() override;

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT

 private:
  // Takes the obstacle scans that arrived (free_ahead_); false: their source left ENABLED.
  [[nodiscard]] bool take_obstacles() noexcept;
  void close_device() noexcept;

  Parameter& device_;
  Parameter& chassis_;
  Parameter& axis_forward_;
  Parameter& axis_turn_;
  Parameter& deadman_button_;
  Parameter& deadband_;
  Parameter& speed_scale_;
  InputOneOf<interfaces::Scan2dData, interfaces::LadarData>& obstacles_;
  Parameter& slow_distance_;
  Parameter& silence_ms_;  // formerly obstacle_timeout_ms
  int fd_ = -1;
  char path_[256] = {};
  interfaces::JoystickData state_{};
  JsEventDecoder events_;  // the device's bytes, an event split across reads kept
  interfaces::ChassisParams limits_{};
  tims::Address chassis_address_;
  std::array<std::byte, 512> reply_{};
  double free_ahead_ = 0.0;
};

}  // namespace rack::components
