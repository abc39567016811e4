// Joystick's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (rack/interfaces/devices.h's JoystickData).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

inline constexpr FieldUnit kJoystickUnits[] = {{"vx", "m/s"}, {"omega", "rad/s"}, {"free_ahead", "m"}};
inline constexpr DataTypeInfo kJoystickType = data_type_info<interfaces::JoystickData>("JoystickData", {},
                                                                                       kJoystickUnits);

}  // namespace rack::components
