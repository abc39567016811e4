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
inline constexpr FieldUnit kObjRecogUnits[] = {
    {"process_ms", "ms"},  {"x", "m"},        {"y", "m"},        {"z", "m"},
    {"roll", "rad"},       {"pitch", "rad"},  {"yaw", "rad"},    {"vx", "m/s"},
    {"vy", "m/s"},         {"vz", "m/s"},     {"size_x", "m"},   {"size_y", "m"},
    {"size_z", "m"},       {"image_x", "px"}, {"image_y", "px"}, {"image_width", "px"},
    {"image_height", "px"}};
inline constexpr DataTypeInfo kObjRecogType = data_type_info<interfaces::ObjRecogData>("ObjRecogData", kObjRecogNames,
                                                                                       kObjRecogUnits);

}  // namespace rack::components
