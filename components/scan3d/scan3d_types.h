// Scan3D's declaration (rack_add_class DATA and COMMANDS in CMakeLists.txt): the sample
// type it publishes (Scan3dData) with the names of its modes, and its class commands
// with their bodies. No other class reads them; tools learn them from the class
// description.
//
// Conventions as in rack/interfaces/robot.h (SI units, fixed-size payloads with a
// count, the sample's time is the SampleHeader's). Scan3D points are in the ROBOT
// frame: x forward, y left, z up, origin on the floor below the robot's reference
// point (so the ground plane is z ~ 0).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "common/scan3d_geometry.h"  // kScan3dMode*: the servo-ladar geometry LadarSim shares
#include "rack/core/class_types.h"
#include "rack/tims/payload.h"

// The payload types (namespace rack::interfaces, as every sample type's, so that code
// naming them did not change when they moved here from components/interfaces).
namespace rack::interfaces {

// Scan3D (class Scan3D): one processed 3-D scan. A scan is one sweep of the servo
// drive (or one PCD file), downsampled (voxel grid), cleaned (statistical outlier
// removal) and typed against the ground plane found by RANSAC: points on the plane
// are kScanPointGround, points above `ceiling_height` kScanPointCeiling, the rest
// kScanPointObstacle (objects). Without a ground plane the points stay
// kScanPointNormal. Bounded: at most kScan3dMaxPoints points (the processing keeps
// the count below it; the sample is about 0.7 MB: give the component a short ring,
// and a `compress: zstd` network to carry it between hosts).
inline constexpr uint32_t kScan3dMaxPoints = 40000;
// The sample's time is the sweep's first 2-D scan (a file's: when it was read).
struct Scan3dData {
  int64_t duration_ns = 0;   // the sweep: first to last 2-D scan (0 for a file)
  uint32_t scan_number = 0;  // scans published since ON
  uint32_t point_count = 0;  // points below
  uint32_t raw_points = 0;   // points assembled before processing
  uint32_t ground_points = 0;
  uint32_t object_points = 0;
  uint32_t ceiling_points = 0;
  uint32_t ladar_scans = 0;  // 2-D scans in this sweep (0 for a file)
  uint32_t bad_input = 0;    // inputs skipped since ON (malformed PCD files, empty or unusable ladar scans)
  uint8_t mode = 0;          // kScan3dMode*
  uint8_t ground_valid = 0;  // ground_* below hold a plane
  uint8_t pad_[2] = {};
  float process_ms = 0.0F;  // PCL processing time of this scan
  // Ground plane a x + b y + c z + d = 0, robot frame, (a, b, c) unit with c > 0.
  float ground_a = 0.0F, ground_b = 0.0F, ground_c = 0.0F, ground_d = 0.0F;
  float x[kScan3dMaxPoints] = {};  // m, robot frame
  float y[kScan3dMaxPoints] = {};
  float z[kScan3dMaxPoints] = {};
  float intensity[kScan3dMaxPoints] = {};  // the ladar's (device units; 0 when none)
  uint8_t type[kScan3dMaxPoints] = {};     // kScanPoint* (rack/interfaces/robot.h)
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(Scan3dData, duration_ns),
                      RACK_FIELD(Scan3dData, scan_number),
                      RACK_FIELD(Scan3dData, point_count),
                      RACK_FIELD(Scan3dData, raw_points),
                      RACK_FIELD(Scan3dData, ground_points),
                      RACK_FIELD(Scan3dData, object_points),
                      RACK_FIELD(Scan3dData, ceiling_points),
                      RACK_FIELD(Scan3dData, ladar_scans),
                      RACK_FIELD(Scan3dData, bad_input),
                      RACK_FIELD(Scan3dData, mode),
                      RACK_FIELD(Scan3dData, ground_valid),
                      RACK_FIELD(Scan3dData, process_ms),
                      RACK_FIELD(Scan3dData, ground_a),
                      RACK_FIELD(Scan3dData, ground_b),
                      RACK_FIELD(Scan3dData, ground_c),
                      RACK_FIELD(Scan3dData, ground_d),
                      RACK_FIELD(Scan3dData, x),
                      RACK_FIELD(Scan3dData, y),
                      RACK_FIELD(Scan3dData, z),
                      RACK_FIELD(Scan3dData, intensity),
                      RACK_FIELD(Scan3dData, type)};
  }
};

// GET_RANGE_IMAGE (request; body Scan3dRangeImageRequest or empty for the component's
// parameters) -> RANGE_IMAGE reply (Scan3dRangeImage) of the newest scan, seen from the
// sensor's position (a spherical image made by PCL's RangeImage), or ERROR when there
// is no scan yet or the image would not fit.
inline constexpr int8_t kScan3dGetRangeImage = 21;
inline constexpr int8_t kScan3dRangeImageReply = -21;
inline constexpr uint32_t kScan3dRangeImageMaxPixels = 64 * 1024;
struct Scan3dRangeImageRequest {
  float angular_resolution_deg = 0.0F;  // 0: the component's range_image_res_deg; at least 0.2
  uint32_t pad_ = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(Scan3dRangeImageRequest, angular_resolution_deg)};
  }
};
struct Scan3dRangeImage {
  uint32_t width = 0;               // columns: azimuth, from angle_left (left) to the right
  uint32_t height = 0;              // rows: elevation, from angle_top (up) downwards
  float angular_resolution = 0.0F;  // rad per pixel
  float angle_left = 0.0F;          // rad, azimuth of column 0 (robot frame, + left)
  float angle_top = 0.0F;           // rad, elevation of row 0 (+ up)
  uint32_t scan_number = 0;         // the Scan3dData it was made from
  int64_t scan_time_ns = 0;
  float range[kScan3dRangeImageMaxPixels] = {};  // m, row-major; 0: nothing seen in that direction
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(Scan3dRangeImage, width),
                      RACK_FIELD(Scan3dRangeImage, height),
                      RACK_FIELD(Scan3dRangeImage, angular_resolution),
                      RACK_FIELD(Scan3dRangeImage, angle_left),
                      RACK_FIELD(Scan3dRangeImage, angle_top),
                      RACK_FIELD(Scan3dRangeImage, scan_number),
                      RACK_FIELD(Scan3dRangeImage, scan_time_ns),
                      RACK_FIELD(Scan3dRangeImage, range)};
  }
};

// STORE_DATA (request; body Scan3dStoreData, or empty: `store_dir`/scan3d_<number>.pcd)
// writes the newest scan as a binary PCD file (fields x y z intensity type). Reply OK,
// or ERROR with the reason (no scan yet, cannot write the file).
inline constexpr int8_t kScan3dStoreData = 22;
struct Scan3dStoreData {
  char path[240] = {};  // file to write (NUL-terminated); empty: the default name
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(Scan3dStoreData, path)}; }
};

}  // namespace rack::interfaces

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
