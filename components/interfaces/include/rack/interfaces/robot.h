// The interfaces of RACK's mobile-robot classes: the data types and class commands
// that classes in more than one folder publish, read or send, so that none of them
// includes another class's folder. Chassis (ChassisSim, ChassisCan, ChassisReplay),
// Ladar (LadarSim, LadarHokuyo, LadarSick, LadarReplay, LadarPlayback) and Scan2D
// (Scan2D, Scan2dPlayback) have several implementations; Odometry (read by Position,
// Scan2D, Scan3D; played back), Position (read by Pilot, Evaluator, Scan3D; MCL sends
// UPDATE) and MCL's estimate (read by Evaluator and TrajectoryWriter) are read by other
// classes. Path: rack/interfaces/navigation.h. A type or command only its own class
// uses is declared in that class's folder (components/<class>/<class>_types.h), as
// Odometry's RESET and MCL's INIT are.
//
// Conventions, for every type of a class (here and in the folders):
// - SI units: metres, radians, seconds, metres per second, volts. RACK used
//   millimetres and integer angles; doubles keep the maths out of every consumer.
// - Poses are 2-D (x, y, phi) in a right-handed frame, phi counter-clockwise from x,
//   normalised to (-pi, pi].
// - The sample's time is the SampleHeader's (TiMS `wire::SampleHeader::time_ns`, host
//   clock); a type repeats a time only where it refers to another moment.
// - Plain fixed-size payloads (no pointers, no heavy includes), so that tools can
//   decode them and a receiver can convert their byte order (tims/payload.h). Arrays
//   are fixed-capacity with a count; entries past the count are unspecified.
//
// Real-time contract: plain data; everything here is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/tims/address.h"
#include "rack/tims/payload.h"

namespace rack::interfaces {

// ---------------------------------------------------------------------------
// Chassis (class Chassis): the drive. Published each cycle: what the wheels did
// since the previous sample (odometry increments, robot frame of the previous
// sample), the measured velocities, and who may drive.
struct ChassisData {
  double delta_x = 0.0;         // m, forward, since the previous sample
  double delta_y = 0.0;         // m, left
  double delta_phi = 0.0;       // rad
  double vx = 0.0;              // m/s, measured
  double vy = 0.0;              // m/s
  double omega = 0.0;           // rad/s
  double battery = 0.0;         // V (0: unknown)
  uint32_t active_pilot = 0;    // raw tims::Address of the pilot allowed to MOVE; 0: none
  uint32_t watchdog_stops = 0;  // times the command watchdog stopped the robot since ON
  // Simulation only (ChassisSim): the true pose, for evaluating localisation. A real
  // chassis leaves truth_valid false and the pose zero.
  uint8_t truth_valid = 0;
  uint8_t pad_[7] = {};
  double truth_x = 0.0;
  double truth_y = 0.0;
  double truth_phi = 0.0;
  // Simulation only: moves refused because the outline would have entered an occupied
  // map cell (ChassisSim with a `map`), since ON.
  uint32_t collisions = 0;
  uint32_t pad2_ = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ChassisData, delta_x),
                      RACK_FIELD(ChassisData, delta_y),
                      RACK_FIELD(ChassisData, delta_phi),
                      RACK_FIELD(ChassisData, vx),
                      RACK_FIELD(ChassisData, vy),
                      RACK_FIELD(ChassisData, omega),
                      RACK_FIELD(ChassisData, battery),
                      RACK_FIELD(ChassisData, active_pilot),
                      RACK_FIELD(ChassisData, watchdog_stops),
                      RACK_FIELD(ChassisData, truth_valid),
                      RACK_FIELD(ChassisData, truth_x),
                      RACK_FIELD(ChassisData, truth_y),
                      RACK_FIELD(ChassisData, truth_phi),
                      RACK_FIELD(ChassisData, collisions)};
  }
};

// MOVE (request): drive at these velocities until the next MOVE. Accepted only from
// the active pilot (the request's source, command mailbox or any mailbox of that
// component); others get ERROR. Velocities are clamped to the chassis limits.
inline constexpr int8_t kChassisMove = 21;
struct ChassisMove {
  double vx = 0.0;     // m/s
  double vy = 0.0;     // m/s (0 on a differential drive)
  double omega = 0.0;  // rad/s
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ChassisMove, vx), RACK_FIELD(ChassisMove, vy), RACK_FIELD(ChassisMove, omega)};
  }
};
// SET_ACTIVE_PILOT (request): from now on only `pilot` may MOVE; 0 releases the
// chassis. The robot stops when the active pilot changes.
inline constexpr int8_t kChassisSetActivePilot = 22;
struct ChassisSetActivePilot {
  uint32_t pilot = 0;  // raw tims::Address (any mailbox of the pilot component)
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(ChassisSetActivePilot, pilot)}; }
};
// GET_PARAMS (request, no body) -> PARAMS reply with ChassisParams.
inline constexpr int8_t kChassisGetParams = 23;
inline constexpr int8_t kChassisParamsReply = -21;
struct ChassisParams {
  double vx_max = 0.0;          // m/s
  double vx_min = 0.0;          // m/s (slowest useful forward speed)
  double omega_max = 0.0;       // rad/s
  double acc_max = 0.0;         // m/s^2
  double dec_max = 0.0;         // m/s^2 (braking)
  double boundary_front = 0.0;  // m, robot outline from the reference point
  double boundary_back = 0.0;
  double boundary_left = 0.0;
  double boundary_right = 0.0;
  double safety_margin = 0.0;  // m, kept free around the outline
  int64_t watchdog_ns = 0;     // the robot stops when no MOVE came for this long
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ChassisParams, vx_max),         RACK_FIELD(ChassisParams, vx_min),
                      RACK_FIELD(ChassisParams, omega_max),      RACK_FIELD(ChassisParams, acc_max),
                      RACK_FIELD(ChassisParams, dec_max),        RACK_FIELD(ChassisParams, boundary_front),
                      RACK_FIELD(ChassisParams, boundary_back),  RACK_FIELD(ChassisParams, boundary_left),
                      RACK_FIELD(ChassisParams, boundary_right), RACK_FIELD(ChassisParams, safety_margin),
                      RACK_FIELD(ChassisParams, watchdog_ns)};
  }
};

// ---------------------------------------------------------------------------
// Ladar (class Ladar): one planar range scan in the sensor's frame. Beam i points at
// start_angle + i * angle_step; the scan took `duration_ns` (the sample's time is its
// start). A range <= 0 or > max_range means no echo.
inline constexpr uint32_t kLadarMaxBeams = 1081;  // 270 deg at 0.25 deg, as a SICK LMS1xx
struct LadarData {
  int64_t duration_ns = 0;
  float max_range = 0.0F;    // m
  float min_range = 0.0F;    // m
  float start_angle = 0.0F;  // rad
  float angle_step = 0.0F;   // rad
  uint32_t beam_count = 0;
  uint32_t pad_ = 0;
  float range[kLadarMaxBeams] = {};      // m
  float intensity[kLadarMaxBeams] = {};  // device units (0 when none)
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(LadarData, duration_ns), RACK_FIELD(LadarData, max_range),
                      RACK_FIELD(LadarData, min_range),   RACK_FIELD(LadarData, start_angle),
                      RACK_FIELD(LadarData, angle_step),  RACK_FIELD(LadarData, beam_count),
                      RACK_FIELD(LadarData, range),       RACK_FIELD(LadarData, intensity)};
  }
};

// ---------------------------------------------------------------------------
// Odometry (class Odometry): the pose integrated from chassis increments since the
// last RESET, in the odometry frame (drifts; never jumps except on RESET).
struct OdometryData {
  double x = 0.0;
  double y = 0.0;
  double phi = 0.0;
  double vx = 0.0;        // m/s
  double omega = 0.0;     // rad/s
  double distance = 0.0;  // m travelled since RESET (path length)
  uint32_t resets = 0;    // RESETs since ON
  uint32_t pad_ = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(OdometryData, x),     RACK_FIELD(OdometryData, y),
                      RACK_FIELD(OdometryData, phi),   RACK_FIELD(OdometryData, vx),
                      RACK_FIELD(OdometryData, omega), RACK_FIELD(OdometryData, distance),
                      RACK_FIELD(OdometryData, resets)};
  }
};

// ---------------------------------------------------------------------------
// Position (class Position): the robot's pose in the map frame = the reference pose
// (set by UPDATE) composed with the odometry travelled since the reference's time.
struct PositionData {
  double x = 0.0;
  double y = 0.0;
  double phi = 0.0;
  double var_x = 0.0;             // m^2
  double var_y = 0.0;             // m^2
  double var_phi = 0.0;           // rad^2
  int64_t reference_time_ns = 0;  // time of the last UPDATE's pose (0: never updated)
  uint32_t updates = 0;           // UPDATEs accepted since ON
  uint32_t pad_ = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(PositionData, x),
                      RACK_FIELD(PositionData, y),
                      RACK_FIELD(PositionData, phi),
                      RACK_FIELD(PositionData, var_x),
                      RACK_FIELD(PositionData, var_y),
                      RACK_FIELD(PositionData, var_phi),
                      RACK_FIELD(PositionData, reference_time_ns),
                      RACK_FIELD(PositionData, updates)};
  }
};
// UPDATE (request): the robot was at this pose at `time_ns` (e.g. MCL's estimate for
// a scan). Position looks up the odometry at that time (Odometry GET_DATA by time),
// re-anchors, and replies OK; ERROR when the odometry has no sample for that time.
inline constexpr int8_t kPositionUpdate = 21;
struct PositionUpdate {
  int64_t time_ns = 0;
  double x = 0.0;
  double y = 0.0;
  double phi = 0.0;
  double var_x = 0.0;
  double var_y = 0.0;
  double var_phi = 0.0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(PositionUpdate, time_ns), RACK_FIELD(PositionUpdate, x),
                      RACK_FIELD(PositionUpdate, y),       RACK_FIELD(PositionUpdate, phi),
                      RACK_FIELD(PositionUpdate, var_x),   RACK_FIELD(PositionUpdate, var_y),
                      RACK_FIELD(PositionUpdate, var_phi)};
  }
};

// ---------------------------------------------------------------------------
// Scan2D (class Scan2D): a ladar scan as points in the ROBOT frame (mounting offset
// applied, range window and filters applied). Point i came from a beam; points with
// no echo are left out.
inline constexpr uint32_t kScan2dMaxPoints = kLadarMaxBeams;
// Point types, RACK's.
inline constexpr uint8_t kScanPointNormal = 0;
inline constexpr uint8_t kScanPointObstacle = 1;
inline constexpr uint8_t kScanPointDynObstacle = 2;
inline constexpr uint8_t kScanPointMaxRange = 3;  // no echo within max_range (x/y at max range)
// Scan3D (components/scan3d/scan3d_types.h) types its points against the ground plane:
// ground, ceiling, and kScanPointObstacle for everything in between (objects).
inline constexpr uint8_t kScanPointGround = 4;
inline constexpr uint8_t kScanPointCeiling = 5;
struct Scan2dData {
  int64_t duration_ns = 0;
  float max_range = 0.0F;  // m
  uint32_t point_count = 0;
  // Where the scan was taken in the odometry frame (Odometry at the scan's time), so a
  // consumer need not look it up; valid when odometry_valid.
  double odometry_x = 0.0;
  double odometry_y = 0.0;
  double odometry_phi = 0.0;
  uint8_t odometry_valid = 0;
  uint8_t pad_[7] = {};
  float x[kScan2dMaxPoints] = {};        // m, robot frame
  float y[kScan2dMaxPoints] = {};        // m
  float range[kScan2dMaxPoints] = {};    // m, from the sensor (for sensor models)
  float bearing[kScan2dMaxPoints] = {};  // rad, from the sensor's axis, sensor frame
  uint8_t type[kScan2dMaxPoints] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(Scan2dData, duration_ns),
                      RACK_FIELD(Scan2dData, max_range),
                      RACK_FIELD(Scan2dData, point_count),
                      RACK_FIELD(Scan2dData, odometry_x),
                      RACK_FIELD(Scan2dData, odometry_y),
                      RACK_FIELD(Scan2dData, odometry_phi),
                      RACK_FIELD(Scan2dData, odometry_valid),
                      RACK_FIELD(Scan2dData, x),
                      RACK_FIELD(Scan2dData, y),
                      RACK_FIELD(Scan2dData, range),
                      RACK_FIELD(Scan2dData, bearing),
                      RACK_FIELD(Scan2dData, type)};
  }
};

// ---------------------------------------------------------------------------
// MCL (class MCL): Monte Carlo localisation's estimate in the map frame, with a
// bounded subset of its particles for display.
inline constexpr uint32_t kMclMaxShownParticles = 256;
struct MclData {
  double x = 0.0;
  double y = 0.0;
  double phi = 0.0;
  double covariance[9] = {};           // row-major 3x3 over (x, y, phi)
  int64_t scan_time_ns = 0;            // the scan this estimate is for
  uint32_t particle_count = 0;         // particles in the filter now
  uint32_t updates = 0;                // observation updates since ON or INIT
  float effective_sample_size = 0.0F;  // ESS / particle_count, in (0, 1]
  uint32_t injected = 0;               // particles replaced by random ones at the last update
  uint32_t shown = 0;                  // particles below
  uint32_t pad_ = 0;
  float particle_x[kMclMaxShownParticles] = {};
  float particle_y[kMclMaxShownParticles] = {};
  float particle_phi[kMclMaxShownParticles] = {};
  float particle_weight[kMclMaxShownParticles] = {};  // normalised over the shown ones
  // Added by the MCL component (fields at the end): how well the scan fits the map at
  // the particles, per point (geometric mean of the likelihood field, in (0, 1]); one
  // half of MCL's recovery evidence (the other: the beams' consistency with the map).
  float fit = 0.0F;
  uint32_t pad2_ = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(MclData, x),
                      RACK_FIELD(MclData, y),
                      RACK_FIELD(MclData, phi),
                      RACK_FIELD(MclData, covariance),
                      RACK_FIELD(MclData, scan_time_ns),
                      RACK_FIELD(MclData, particle_count),
                      RACK_FIELD(MclData, updates),
                      RACK_FIELD(MclData, effective_sample_size),
                      RACK_FIELD(MclData, injected),
                      RACK_FIELD(MclData, shown),
                      RACK_FIELD(MclData, particle_x),
                      RACK_FIELD(MclData, particle_y),
                      RACK_FIELD(MclData, particle_phi),
                      RACK_FIELD(MclData, particle_weight),
                      RACK_FIELD(MclData, fit)};
  }
};
}  // namespace rack::interfaces
