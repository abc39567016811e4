// Scan3D's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (rack/interfaces/perception.h's Scan3dData) with the names of its
// modes, and its class commands.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/perception.h"

namespace rack::components {

inline constexpr ValueName kScan3dModeNames[] = {{interfaces::kScan3dModeRoll, "ROLL"},
                                                 {interfaces::kScan3dModePitch, "PITCH"},
                                                 {interfaces::kScan3dModeYaw, "YAW"},
                                                 {interfaces::kScan3dModeFile, "FILE"}};
inline constexpr FieldValueNames kScan3dNames[] = {{"mode", kScan3dModeNames}};
inline constexpr FieldUnit kScan3dUnits[] = {
    {"duration_ns", "ns"}, {"process_ms", "ms"}, {"x", "m"}, {"y", "m"}, {"z", "m"}};
inline constexpr DataTypeInfo kScan3dType = data_type_info<interfaces::Scan3dData>("Scan3dData", kScan3dNames,
                                                                                   kScan3dUnits);
inline constexpr DataTypeInfo kScan3dRangeImageRequestBody = data_type_info<interfaces::Scan3dRangeImageRequest>(
    "Scan3dRangeImageRequest");
inline constexpr DataTypeInfo kScan3dStoreDataBody = data_type_info<interfaces::Scan3dStoreData>("Scan3dStoreData");
inline constexpr CommandInfo kScan3dCommands[] = {
    {"GET_RANGE_IMAGE", interfaces::kScan3dGetRangeImage, &kScan3dRangeImageRequestBody,
     "range image of the newest scan (angular_resolution_deg; none: the parameter)"},
    {"STORE_DATA", interfaces::kScan3dStoreData, &kScan3dStoreDataBody,
     "write the newest scan as a PCD file (path; none: store_dir)"}};

}  // namespace rack::components
