// Joystick's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (JoystickData). No other class reads it.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/tims/payload.h"

// The payload types (namespace rack::interfaces, as every sample type's, so that code
// naming them did not change when they moved here from components/interfaces).
namespace rack::interfaces {

// Joystick (class Joystick): the state of a game controller (Linux joystick API),
// axes scaled to [-1, 1], and the velocity command it stands for when it drives a
// chassis (axis_forward/axis_turn, scaled by the chassis limits; zero when the
// dead-man button is configured and not held).
inline constexpr uint32_t kJoystickMaxAxes = 8;
struct JoystickData {
  float axis[kJoystickMaxAxes] = {};  // [-1, 1]; right/down positive as the device reports
  uint32_t buttons = 0;               // bit i: button i pressed
  uint32_t axis_count = 0;
  uint32_t button_count = 0;
  uint32_t events = 0;          // js_events read since ON
  uint32_t bad_events = 0;      // short reads, unknown types, out-of-range numbers
  uint32_t moves_rejected = 0;  // MOVEs the chassis refused (another pilot is active)
  double vx = 0.0;              // m/s, the command sent to the chassis
  double omega = 0.0;           // rad/s
  double free_ahead = -1.0;     // m free ahead in the corridor (obstacles), -1: not used
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(JoystickData, axis),           RACK_FIELD(JoystickData, buttons),
                      RACK_FIELD(JoystickData, axis_count),     RACK_FIELD(JoystickData, button_count),
                      RACK_FIELD(JoystickData, events),         RACK_FIELD(JoystickData, bad_events),
                      RACK_FIELD(JoystickData, moves_rejected), RACK_FIELD(JoystickData, vx),
                      RACK_FIELD(JoystickData, omega),          RACK_FIELD(JoystickData, free_ahead)};
  }
};

}  // namespace rack::interfaces

namespace rack::components {

inline constexpr FieldUnit kJoystickUnits[] = {{"vx", "m/s"}, {"omega", "rad/s"}, {"free_ahead", "m"}};
inline constexpr DataTypeInfo kJoystickType = data_type_info<interfaces::JoystickData>("JoystickData", {},
                                                                                       kJoystickUnits);

}  // namespace rack::components
