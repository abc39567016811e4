// The declaration of this folder's classes, ObjRecogLaser and ObjRecogCamera
// (rack_add_class DATA in CMakeLists.txt): the sample type both publish
// (ObjRecogData) with the names of its frames. No other class reads it.
//
// Conventions as in rack/interfaces/robot.h. Objects from a camera are in the CAMERA's
// optical frame (OpenCV's: x right, y down, z forward along the optical axis); objects
// from laser scans are in the robot frame at the scan's time (z = 0). `frame` says
// which.
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

// ObjRecog (class ObjRecog): recognised objects (RACK's obj_recog_object), one array
// entry per object. Velocities come from following an object over samples (by
// marker id, or by a nearest-neighbour Kalman tracker); 0 until seen twice.
inline constexpr uint32_t kObjRecogMaxObjects = 64;
inline constexpr uint8_t kObjTypeUnknown = 0;
inline constexpr uint8_t kObjTypeFiducial = 1;      // ArUco marker: id = marker id, full 3-D pose
inline constexpr uint8_t kObjTypePerson = 2;        // HOG people detector: position from the box
inline constexpr uint8_t kObjTypeLaserCluster = 3;  // a tracked cluster of laser points
inline constexpr uint8_t kObjFrameCamera = 0;       // camera optical frame (x right, y down, z forward)
inline constexpr uint8_t kObjFrameRobot = 1;        // robot frame (x forward, y left, z up)
struct ObjRecogData {
  uint32_t object_count = 0;
  uint32_t inputs = 0;     // images or scans processed since ON
  uint32_t bad_input = 0;  // images or scans skipped since ON (wrong size or format, empty)
  uint8_t frame = 0;       // kObjFrame*
  uint8_t pad_[3] = {};
  float process_ms = 0.0F;  // time spent on this sample
  uint32_t pad2_ = 0;
  uint32_t id[kObjRecogMaxObjects] = {};        // marker id, or track id
  uint8_t type[kObjRecogMaxObjects] = {};       // kObjType*
  float probability[kObjRecogMaxObjects] = {};  // 0..1 (HOG: squashed SVM score)
  float x[kObjRecogMaxObjects] = {};            // m, position (centre) in `frame`
  float y[kObjRecogMaxObjects] = {};
  float z[kObjRecogMaxObjects] = {};
  float roll[kObjRecogMaxObjects] = {};  // rad, orientation (fiducials; 0 otherwise), ZYX Euler in `frame`
  float pitch[kObjRecogMaxObjects] = {};
  float yaw[kObjRecogMaxObjects] = {};
  float vx[kObjRecogMaxObjects] = {};  // m/s, in `frame` (laser: over ground, odometry-compensated)
  float vy[kObjRecogMaxObjects] = {};
  float vz[kObjRecogMaxObjects] = {};
  float size_x[kObjRecogMaxObjects] = {};  // m, extent along the frame's axes
  float size_y[kObjRecogMaxObjects] = {};
  float size_z[kObjRecogMaxObjects] = {};
  int32_t image_x[kObjRecogMaxObjects] = {};  // pixels, bounding box in the image (camera only)
  int32_t image_y[kObjRecogMaxObjects] = {};
  int32_t image_width[kObjRecogMaxObjects] = {};
  int32_t image_height[kObjRecogMaxObjects] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ObjRecogData, object_count),
                      RACK_FIELD(ObjRecogData, inputs),
                      RACK_FIELD(ObjRecogData, bad_input),
                      RACK_FIELD(ObjRecogData, frame),
                      RACK_FIELD(ObjRecogData, process_ms),
                      RACK_FIELD(ObjRecogData, id),
                      RACK_FIELD(ObjRecogData, type),
                      RACK_FIELD(ObjRecogData, probability),
                      RACK_FIELD(ObjRecogData, x),
                      RACK_FIELD(ObjRecogData, y),
                      RACK_FIELD(ObjRecogData, z),
                      RACK_FIELD(ObjRecogData, roll),
                      RACK_FIELD(ObjRecogData, pitch),
                      RACK_FIELD(ObjRecogData, yaw),
                      RACK_FIELD(ObjRecogData, vx),
                      RACK_FIELD(ObjRecogData, vy),
                      RACK_FIELD(ObjRecogData, vz),
                      RACK_FIELD(ObjRecogData, size_x),
                      RACK_FIELD(ObjRecogData, size_y),
                      RACK_FIELD(ObjRecogData, size_z),
                      RACK_FIELD(ObjRecogData, image_x),
                      RACK_FIELD(ObjRecogData, image_y),
                      RACK_FIELD(ObjRecogData, image_width),
                      RACK_FIELD(ObjRecogData, image_height)};
  }
};

}  // namespace rack::interfaces

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
