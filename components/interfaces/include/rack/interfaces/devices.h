// Data types and class commands of RACK's device classes: GPS, Joystick, ServoDrive,
// Camera (the
// Chassis and Ladar drivers publish rack/interfaces/robot.h's types).
//
// Conventions as in robot.h (SI units, fixed-size payloads, the sample's time is the
// SampleHeader's: for a device it is the receive time of the data on this host).
// Geographic angles are degrees, as every GNSS user expects; the field names say so.
//
// Real-time contract: plain data; everything here is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/tims/payload.h"

namespace rack::interfaces {

// ---------------------------------------------------------------------------
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

// ---------------------------------------------------------------------------
// Joystick (class Joystick): the state of a game controller (Linux joystick API),
// axes scaled to [-1, 1], and the velocity command it stands for when it drives a
// chassis (axis_forward/axis_turn, scaled by the chassis limits; zero when the
// dead-man button is configured and not held).
inline constexpr uint32_t kJoystickMaxAxes = 8;
struct JoystickData {
  float axis[kJoystickMaxAxes] = {};  // [-1, 1]; right/down positive as the device reports
  uint32_t buttons = 0;               // bit i: button i pressed
  uint32_t axis_count = 0;
  uint32_t button_count = 0;
  uint32_t events = 0;          // js_events read since ON
  uint32_t bad_events = 0;      // short reads, unknown types, out-of-range numbers
  uint32_t moves_rejected = 0;  // MOVEs the chassis refused (another pilot is active)
  double vx = 0.0;              // m/s, the command sent to the chassis
  double omega = 0.0;           // rad/s
  double free_ahead = -1.0;     // m free ahead in the corridor (obstacles), -1: not used
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(JoystickData, axis),           RACK_FIELD(JoystickData, buttons),
                      RACK_FIELD(JoystickData, axis_count),     RACK_FIELD(JoystickData, button_count),
                      RACK_FIELD(JoystickData, events),         RACK_FIELD(JoystickData, bad_events),
                      RACK_FIELD(JoystickData, moves_rejected), RACK_FIELD(JoystickData, vx),
                      RACK_FIELD(JoystickData, omega),          RACK_FIELD(JoystickData, free_ahead)};
  }
};

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
