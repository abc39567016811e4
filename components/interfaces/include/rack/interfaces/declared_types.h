// The declarations (rack_add_class DATA and COMMANDS, cmake/RackClass.cmake) of the
// interfaces that classes in several folders implement, each declared once and
// referenced by each of them: Chassis (ChassisSim, ChassisCan, ChassisReplay), Ladar
// (LadarSim, LadarHokuyo, LadarSick, LadarReplay), ServoDrive (ServoDriveSim,
// ServoDriveCan) and Scan2D (Scan2D, Scan2dPlayback). A class of its own declares its
// data type and commands in its folder (components/<class>/<class>_types.h), as a
// class built outside the tree does (rack/core/class_types.h).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/robot.h"

namespace rack::interfaces::declared {

template <typename T>
inline constexpr DataTypeInfo info(const char* name, std::span<const FieldValueNames> value_names = {},
                                   std::span<const FieldUnit> units = {}) {
  return data_type_info<T>(name, value_names, units);
}

// The pilot whose commands the chassis follows: a TiMS address (0: none).
inline constexpr FieldValueNames kChassisNames[] = {{"active_pilot", {}, true}};

// The units of the fields (rack/interfaces/robot.h's comments); the servo axis' unit is
// its driver's (metres or radians), so ServoDriveData declares none.
inline constexpr FieldUnit kChassisUnits[] = {{"delta_x", "m"},    {"delta_y", "m"}, {"delta_phi", "rad"},
                                              {"vx", "m/s"},       {"vy", "m/s"},    {"omega", "rad/s"},
                                              {"battery", "V"},    {"truth_x", "m"}, {"truth_y", "m"},
                                              {"truth_phi", "rad"}};
inline constexpr FieldUnit kLadarUnits[] = {{"duration_ns", "ns"},  {"max_range", "m"},    {"min_range", "m"},
                                            {"start_angle", "rad"}, {"angle_step", "rad"}, {"range", "m"}};
inline constexpr FieldUnit kScan2dUnits[] = {
    {"duration_ns", "ns"},   {"max_range", "m"}, {"odometry_x", "m"}, {"odometry_y", "m"},
    {"odometry_phi", "rad"}, {"x", "m"},         {"y", "m"},          {"range", "m"},
    {"bearing", "rad"}};

inline constexpr DataTypeInfo kChassis = info<ChassisData>("ChassisData", kChassisNames, kChassisUnits);
inline constexpr DataTypeInfo kLadar = info<LadarData>("LadarData", {}, kLadarUnits);
inline constexpr DataTypeInfo kScan2d = info<Scan2dData>("Scan2dData", {}, kScan2dUnits);
inline constexpr DataTypeInfo kServoDrive = info<ServoDriveData>("ServoDriveData");

// Bodies of class commands.
inline constexpr DataTypeInfo kChassisMoveBody = info<ChassisMove>("ChassisMove");
inline constexpr DataTypeInfo kChassisSetActivePilotBody = info<ChassisSetActivePilot>("ChassisSetActivePilot");
inline constexpr DataTypeInfo kServoDriveMovePosBody = info<ServoDriveMovePos>("ServoDriveMovePos");
inline constexpr DataTypeInfo kServoDriveMoveVelBody = info<ServoDriveMoveVel>("ServoDriveMoveVel");

inline constexpr CommandInfo kChassisCommands[] = {
    {"MOVE", kChassisMove, &kChassisMoveBody, "drive at vx, vy (m/s), omega (rad/s); only the active pilot"},
    {"SET_ACTIVE_PILOT", kChassisSetActivePilot, &kChassisSetActivePilotBody,
     "only pilot (an address, 0x...) may MOVE; 0 releases"},
    {"GET_PARAMS", kChassisGetParams, nullptr, "the chassis limits (PARAMS reply)"}};
inline constexpr CommandInfo kServoDriveCommands[] = {
    {"HOME", kServoDriveHome, nullptr, "the current position becomes home"},
    {"MOVE_POS", kServoDriveMovePos, &kServoDriveMovePosBody, "move to position at velocity (0: max)"},
    {"MOVE_VEL", kServoDriveMoveVel, &kServoDriveMoveVelBody, "move at velocity until a limit"}};

}  // namespace rack::interfaces::declared
