// Camera's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (rack/interfaces/devices.h's CameraData: ObjRecogCamera and rack-gui read
// it) with the names of its formats.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

inline constexpr ValueName kCameraFormatNames[] = {
    {interfaces::kCameraRgb8, "RGB8"}, {interfaces::kCameraMono8, "MONO8"}, {interfaces::kCameraJpeg, "JPEG"}};
inline constexpr FieldValueNames kCameraNames[] = {{"format", kCameraFormatNames}};
inline constexpr FieldUnit kCameraUnits[] = {{"fx", "px"}, {"fy", "px"}, {"cx", "px"}, {"cy", "px"}};
inline constexpr DataTypeInfo kCameraType = data_type_info<interfaces::CameraData>("CameraData", kCameraNames,
                                                                                   kCameraUnits);

}  // namespace rack::components
