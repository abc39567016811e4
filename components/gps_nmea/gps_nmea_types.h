// GpsNmea's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (rack/interfaces/devices.h's GpsData) with the names of its fix values.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

inline constexpr ValueName kGpsFixQualityNames[] = {{interfaces::kGpsFixNone, "NONE"},
                                                    {interfaces::kGpsFixGps, "GPS"},
                                                    {interfaces::kGpsFixDgps, "DGPS"},
                                                    {interfaces::kGpsFixRtkFixed, "RTK_FIXED"},
                                                    {interfaces::kGpsFixRtkFloat, "RTK_FLOAT"}};
inline constexpr ValueName kGpsFixModeNames[] = {{1, "NONE"}, {2, "2D"}, {3, "3D"}};  // GSA's mode (devices.h)
inline constexpr FieldValueNames kGpsNames[] = {{"fix_quality", kGpsFixQualityNames}, {"fix_mode", kGpsFixModeNames}};
inline constexpr FieldUnit kGpsUnits[] = {
    {"latitude_deg", "deg"}, {"longitude_deg", "deg"}, {"altitude", "m"}, {"speed", "m/s"}, {"course_deg", "deg"},
    {"utm_easting", "m"},    {"utm_northing", "m"},    {"x", "m"},        {"y", "m"},       {"utc_ns", "ns"}};
inline constexpr DataTypeInfo kGpsType = data_type_info<interfaces::GpsData>("GpsData", kGpsNames, kGpsUnits);

}  // namespace rack::components
