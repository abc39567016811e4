// The interfaces of RACK's device classes that other classes use: ServoDrive
// (ServoDriveSim, ServoDriveCan; Scan3D and LadarSim read it, Scan3D sends MOVE_POS)
// and Camera (ObjRecogCamera reads it). The Chassis and Ladar drivers publish
// rack/interfaces/robot.h's types; GpsNmea and Joystick declare theirs in their folders.
//
// Conventions as in robot.h (SI units, fixed-size payloads, the sample's time is the
// SampleHeader's: for a device it is the receive time of the data on this host).
//
// Real-time contract: plain data; everything here is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/tims/payload.h"

namespace rack::interfaces {

// ---------------------------------------------------------------------------
// ServoDrive (class ServoDrive): one positioning axis (a pan unit, a lift, a gripper)
// on a CiA 402 drive in profile position mode. Positions in the axis' unit (metres or
// radians, by the driver's counts_per_unit), relative to the home set by HOME.
struct ServoDriveData {
  double position = 0.0;    // unit
  double velocity = 0.0;    // unit/s
  double target = 0.0;      // the set-point being approached (unit)
  uint16_t statusword = 0;  // CiA 402, for diagnostics
  uint8_t target_reached = 0;
  uint8_t homed = 0;
  uint32_t moves = 0;    // MOVE_POS/MOVE_VEL accepted since ON
  uint32_t reached = 0;  // POSITION_REACHED notifications sent since ON
  uint32_t pad_ = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ServoDriveData, position),       RACK_FIELD(ServoDriveData, velocity),
                      RACK_FIELD(ServoDriveData, target),         RACK_FIELD(ServoDriveData, statusword),
                      RACK_FIELD(ServoDriveData, target_reached), RACK_FIELD(ServoDriveData, homed),
                      RACK_FIELD(ServoDriveData, moves),          RACK_FIELD(ServoDriveData, reached)};
  }
};
// HOME (request, no body): the current position becomes the driver's home_position
// (software homing: for drives whose encoder keeps its count). Reply OK.
inline constexpr int8_t kServoDriveHome = 21;
// MOVE_POS (request): move to `position` at `velocity` (0: the driver's max_velocity).
// Reply OK when the drive took the set-point, ERROR outside [position_min,
// position_max] or before HOME; then a POSITION_REACHED notification (body: the
// reached position as one double) goes to the mailbox the MOVE_POS came from when the
// drive reports it. Send MOVE_POS from a mailbox you read (an Endpoint::call's reply
// mailbox discards later messages as stale replies), or poll ServoDriveData's
// target_reached instead.
inline constexpr int8_t kServoDriveMovePos = 22;
struct ServoDriveMovePos {
  double position = 0.0;
  double velocity = 0.0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ServoDriveMovePos, position), RACK_FIELD(ServoDriveMovePos, velocity)};
  }
};
// MOVE_VEL (request): move at `velocity` (sign: direction) until the position limit in
// that direction or the next command; 0 stops where the axis is. Reply OK.
inline constexpr int8_t kServoDriveMoveVel = 23;
struct ServoDriveMoveVel {
  double velocity = 0.0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(ServoDriveMoveVel, velocity)}; }
};
inline constexpr int8_t kServoDrivePositionReached = -21;

// ---------------------------------------------------------------------------
// Camera (class Camera): one image, raw (RGB8 or MONO8, rows top to bottom, no padding)
// or JPEG-encoded (for remote viewing over slow links), with the calibration from the
// driver's OpenCV calibration file. Frames larger than the payload are scaled down
// (aspect kept) by the driver. A fixed-size payload: keep the ring short (ring: 4).
inline constexpr uint32_t kCameraMaxBytes = 640 * 480 * 3;
inline constexpr uint8_t kCameraRgb8 = 1;
inline constexpr uint8_t kCameraMono8 = 2;
inline constexpr uint8_t kCameraJpeg = 3;
struct CameraData {
  uint32_t width = 0;
  uint32_t height = 0;
  uint32_t bytes = 0;       // used bytes of data
  uint32_t frame = 0;       // frames delivered since ON
  uint32_t dropped = 0;     // frames the device gave that were never published (too slow)
  uint32_t bad_frames = 0;  // frames the device failed to deliver or decode
  uint8_t format = 0;       // kCamera*
  uint8_t calibrated = 0;   // the fields below come from a calibration file
  uint8_t pad_[6] = {};
  double fx = 0.0, fy = 0.0;  // focal lengths, pixels (of this image's size)
  double cx = 0.0, cy = 0.0;  // principal point, pixels
  double distortion[5] = {};  // k1 k2 p1 p2 k3 (OpenCV's model)
  uint8_t data[kCameraMaxBytes] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(CameraData, width),      RACK_FIELD(CameraData, height),
                      RACK_FIELD(CameraData, bytes),      RACK_FIELD(CameraData, frame),
                      RACK_FIELD(CameraData, dropped),    RACK_FIELD(CameraData, bad_frames),
                      RACK_FIELD(CameraData, format),     RACK_FIELD(CameraData, calibrated),
                      RACK_FIELD(CameraData, fx),         RACK_FIELD(CameraData, fy),
                      RACK_FIELD(CameraData, cx),         RACK_FIELD(CameraData, cy),
                      RACK_FIELD(CameraData, distortion), RACK_FIELD(CameraData, data)};
  }
};

}  // namespace rack::interfaces
