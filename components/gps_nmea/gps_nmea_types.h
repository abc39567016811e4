// GpsNmea's declaration (rack_add_class DATA in CMakeLists.txt): the sample type it
// publishes (GpsData) with the names of its fix values. No other class reads it.
// Conventions as in rack/interfaces/devices.h; geographic angles are degrees, as every
// GNSS user expects, and the field names say so.
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

// GPS (class Gps): one receiver epoch (NMEA GGA/RMC/GSA/VTG), with the position also
// in UTM and in a local metric frame (x east, y north of the configured origin, in the
// origin's UTM zone, so the frame stays continuous across zone borders).
inline constexpr uint8_t kGpsFixNone = 0;
inline constexpr uint8_t kGpsFixGps = 1;
inline constexpr uint8_t kGpsFixDgps = 2;
inline constexpr uint8_t kGpsFixRtkFixed = 4;
inline constexpr uint8_t kGpsFixRtkFloat = 5;
struct GpsData {
  double latitude_deg = 0.0;   // WGS84, + north
  double longitude_deg = 0.0;  // + east
  double altitude = 0.0;       // m above mean sea level
  double speed = 0.0;          // m/s over ground
  double course_deg = 0.0;     // over ground, clockwise from true north
  double hdop = 0.0;
  double pdop = 0.0;
  double vdop = 0.0;
  double utm_easting = 0.0;   // m, in utm_zone
  double utm_northing = 0.0;  // m
  double x = 0.0;             // m east of the origin (local frame)
  double y = 0.0;             // m north of the origin
  int64_t utc_ns = 0;         // the receiver's UTC for this epoch (0: no date yet)
  uint32_t utm_zone = 0;      // 1..60
  uint8_t utm_north = 1;      // hemisphere
  uint8_t fix_quality = 0;    // kGpsFix*
  uint8_t fix_mode = 1;       // 1 none, 2 2D, 3 3D (GSA)
  uint8_t satellites = 0;     // used in the fix
  // Driver counters since the component was created: accepted sentences and what was rejected.
  uint32_t sentences = 0;
  uint32_t checksum_errors = 0;
  uint32_t malformed = 0;
  uint32_t garbage_bytes = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(GpsData, latitude_deg),
                      RACK_FIELD(GpsData, longitude_deg),
                      RACK_FIELD(GpsData, altitude),
                      RACK_FIELD(GpsData, speed),
                      RACK_FIELD(GpsData, course_deg),
                      RACK_FIELD(GpsData, hdop),
                      RACK_FIELD(GpsData, pdop),
                      RACK_FIELD(GpsData, vdop),
                      RACK_FIELD(GpsData, utm_easting),
                      RACK_FIELD(GpsData, utm_northing),
                      RACK_FIELD(GpsData, x),
                      RACK_FIELD(GpsData, y),
                      RACK_FIELD(GpsData, utc_ns),
                      RACK_FIELD(GpsData, utm_zone),
                      RACK_FIELD(GpsData, utm_north),
                      RACK_FIELD(GpsData, fix_quality),
                      RACK_FIELD(GpsData, fix_mode),
                      RACK_FIELD(GpsData, satellites),
                      RACK_FIELD(GpsData, sentences),
                      RACK_FIELD(GpsData, checksum_errors),
                      RACK_FIELD(GpsData, malformed),
                      RACK_FIELD(GpsData, garbage_bytes)};
  }
};

}  // namespace rack::interfaces

namespace rack::components {

inline constexpr ValueName kGpsFixQualityNames[] = {{interfaces::kGpsFixNone, "NONE"},
                                                    {interfaces::kGpsFixGps, "GPS"},
                                                    {interfaces::kGpsFixDgps, "DGPS"},
                                                    {interfaces::kGpsFixRtkFixed, "RTK_FIXED"},
                                                    {interfaces::kGpsFixRtkFloat, "RTK_FLOAT"}};
inline constexpr ValueName kGpsFixModeNames[] = {{1, "NONE"}, {2, "2D"}, {3, "3D"}};  // GSA's mode (fix_mode above)
inline constexpr FieldValueNames kGpsNames[] = {{"fix_quality", kGpsFixQualityNames}, {"fix_mode", kGpsFixModeNames}};
inline constexpr FieldUnit kGpsUnits[] = {
    {"latitude_deg", "deg"}, {"longitude_deg", "deg"}, {"altitude", "m"}, {"speed", "m/s"}, {"course_deg", "deg"},
    {"utm_easting", "m"},    {"utm_northing", "m"},    {"x", "m"},        {"y", "m"},       {"utc_ns", "ns"}};
inline constexpr DataTypeInfo kGpsType = data_type_info<interfaces::GpsData>("GpsData", kGpsNames, kGpsUnits);

}  // namespace rack::components
