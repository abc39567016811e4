// The declaration of this folder's classes, ObjRecogLaser and ObjRecogCamera
// (rack_add_class DATA in CMakeLists.txt): the sample type both publish
// (rack/interfaces/perception.h's ObjRecogData) with the names of its frames.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/perception.h"

namespace rack::components {

inline constexpr ValueName kObjFrameNames[] = {{interfaces::kObjFrameCamera, "CAMERA"},
                                               {interfaces::kObjFrameRobot, "ROBOT"}};
inline constexpr FieldValueNames kObjRecogNames[] = {{"frame", kObjFrameNames}};
inline constexpr DataTypeInfo kObjRecogType = data_type_info<interfaces::ObjRecogData>("ObjRecogData", kObjRecogNames);

}  // namespace rack::components
