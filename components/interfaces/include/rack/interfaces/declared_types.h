// The data types and class commands the component classes declare (rack_add_class
// DATA and COMMANDS, cmake/RackClass.cmake), each declared once: an interface shared
// by several classes (Chassis for ChassisSim, ChassisCan and ChassisReplay; Ladar;
// ServoDrive; ObjRecog; Evaluator) is named here and referenced by each of them.
// A class built outside the tree declares its own the same way (rack/core/class_types.h).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/demo.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/evaluation.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/perception.h"
#include "rack/interfaces/robot.h"

namespace rack::interfaces::declared {

template <typename T>
inline constexpr DataTypeInfo info(const char* name, std::span<const FieldValueNames> value_names = {}) {
  return data_type_info<T>(name, value_names);
}

// The names of enum values and address fields that tools print beside the raw values
// (rackctl's "names" object), from the interface headers' constants.
constexpr uint32_t u(PilotMode m) { return static_cast<uint32_t>(m); }
constexpr uint32_t u(PilotStatus s) { return static_cast<uint32_t>(s); }
inline constexpr ValueName kPilotModeNames[] = {{u(PilotMode::kHold), "HOLD"},
                                                {u(PilotMode::kFollowPath), "FOLLOW_PATH"},
                                                {u(PilotMode::kDestination), "DESTINATION"}};
inline constexpr ValueName kPilotStatusNames[] = {{u(PilotStatus::kIdle), "IDLE"},
                                                  {u(PilotStatus::kDriving), "DRIVING"},
                                                  {u(PilotStatus::kReached), "REACHED"},
                                                  {u(PilotStatus::kBlocked), "BLOCKED"},
                                                  {u(PilotStatus::kNoPath), "NO_PATH"},
                                                  {u(PilotStatus::kPreempted), "PREEMPTED"},
                                                  {u(PilotStatus::kNoInput), "NO_INPUT"},
                                                  {u(PilotStatus::kPlanning), "PLANNING"},
                                                  {u(PilotStatus::kUnreachable), "UNREACHABLE"}};
inline constexpr FieldValueNames kPilotNames[] = {{"mode", kPilotModeNames}, {"status", kPilotStatusNames}};
inline constexpr ValueName kGpsFixQualityNames[] = {{kGpsFixNone, "NONE"},
                                                    {kGpsFixGps, "GPS"},
                                                    {kGpsFixDgps, "DGPS"},
                                                    {kGpsFixRtkFixed, "RTK_FIXED"},
                                                    {kGpsFixRtkFloat, "RTK_FLOAT"}};
inline constexpr ValueName kGpsFixModeNames[] = {{1, "NONE"}, {2, "2D"}, {3, "3D"}};  // GSA's mode (devices.h)
inline constexpr FieldValueNames kGpsNames[] = {{"fix_quality", kGpsFixQualityNames}, {"fix_mode", kGpsFixModeNames}};
inline constexpr ValueName kCameraFormatNames[] = {
    {kCameraRgb8, "RGB8"}, {kCameraMono8, "MONO8"}, {kCameraJpeg, "JPEG"}};
inline constexpr FieldValueNames kCameraNames[] = {{"format", kCameraFormatNames}};
inline constexpr ValueName kScan3dModeNames[] = {
    {kScan3dModeRoll, "ROLL"}, {kScan3dModePitch, "PITCH"}, {kScan3dModeYaw, "YAW"}, {kScan3dModeFile, "FILE"}};
inline constexpr FieldValueNames kScan3dNames[] = {{"mode", kScan3dModeNames}};
inline constexpr ValueName kObjFrameNames[] = {{kObjFrameCamera, "CAMERA"}, {kObjFrameRobot, "ROBOT"}};
inline constexpr FieldValueNames kObjRecogNames[] = {{"frame", kObjFrameNames}};
// The pilot whose commands the chassis follows: a TiMS address (0: none).
inline constexpr FieldValueNames kChassisNames[] = {{"active_pilot", {}, true}};

inline constexpr DataTypeInfo kGenerator = info<GeneratorData>("GeneratorData");
inline constexpr DataTypeInfo kMonitor = info<MonitorData>("MonitorData");
inline constexpr DataTypeInfo kProbe = info<ProbeData>("ProbeData");
inline constexpr DataTypeInfo kChassis = info<ChassisData>("ChassisData", kChassisNames);
inline constexpr DataTypeInfo kLadar = info<LadarData>("LadarData");
inline constexpr DataTypeInfo kOdometry = info<OdometryData>("OdometryData");
inline constexpr DataTypeInfo kPosition = info<PositionData>("PositionData");
inline constexpr DataTypeInfo kScan2d = info<Scan2dData>("Scan2dData");
inline constexpr DataTypeInfo kMcl = info<MclData>("MclData");
inline constexpr DataTypeInfo kPath = info<PathData>("PathData");
inline constexpr DataTypeInfo kPilot = info<PilotData>("PilotData", kPilotNames);
inline constexpr DataTypeInfo kEvaluator = info<EvaluatorData>("EvaluatorData");
inline constexpr DataTypeInfo kModeSwitchDemo = info<ModeSwitchDemoData>("ModeSwitchDemoData");
inline constexpr DataTypeInfo kGps = info<GpsData>("GpsData", kGpsNames);
inline constexpr DataTypeInfo kJoystick = info<JoystickData>("JoystickData");
inline constexpr DataTypeInfo kServoDrive = info<ServoDriveData>("ServoDriveData");
inline constexpr DataTypeInfo kCamera = info<CameraData>("CameraData", kCameraNames);

// Bodies of class commands.
struct Int64Body {  // the 8-byte integer body of Probe ECHO and ModeSwitchDemo SPIN
  int64_t value = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(Int64Body, value)}; }
};
inline constexpr DataTypeInfo kInt64Body = info<Int64Body>("Int64");
inline constexpr DataTypeInfo kChassisMoveBody = info<ChassisMove>("ChassisMove");
inline constexpr DataTypeInfo kChassisSetActivePilotBody = info<ChassisSetActivePilot>("ChassisSetActivePilot");
inline constexpr DataTypeInfo kPositionUpdateBody = info<PositionUpdate>("PositionUpdate");
inline constexpr DataTypeInfo kMclInitBody = info<MclInit>("MclInit");
inline constexpr DataTypeInfo kPathMakeBody = info<PathMake>("PathMake");
inline constexpr DataTypeInfo kPilotDestinationBody = info<PilotDestination>("PilotDestination");
inline constexpr DataTypeInfo kServoDriveMovePosBody = info<ServoDriveMovePos>("ServoDriveMovePos");
inline constexpr DataTypeInfo kServoDriveMoveVelBody = info<ServoDriveMoveVel>("ServoDriveMoveVel");

inline constexpr CommandInfo kGeneratorCommands[] = {{"RESET", kGeneratorReset, nullptr, "the counter to 0"}};
inline constexpr CommandInfo kProbeCommands[] = {{"ECHO", kProbeEcho, &kInt64Body, "replies OK with the same body"},
                                                 {"THROW", kProbeThrow, nullptr,
                                                  "command() throws: the component goes to ERROR"}};
inline constexpr CommandInfo kModeSwitchDemoCommands[] = {
    {"SYSCALL", kDemoSyscall, nullptr, "write() to /dev/null -> SYSCALL"},
    {"FAULT", kDemoFault, nullptr, "touch a page that is not resident -> FAULT"},
    {"ALLOC", kDemoAlloc, nullptr, "new[] and delete[] -> ALLOC"},
    {"PRIOINV", kDemoPrioInv, nullptr, "lock a std::mutex -> PRIOINV"},
    {"SPIN", kDemoSpin, &kInt64Body, "busy for value ms (0: 300) -> WATCHDOG"},
    {"OVERRUN", kDemoOverrun, nullptr, "the next loop() overruns -> WATCHDOG"},
    {"DEVICE", kDemoDevice, nullptr, "write() to a registered RT device -> nothing"},
    {"CRASH", kDemoCrash, nullptr, "write through a null pointer -> CRASH"},
    {"ABORT", kDemoAbort, nullptr, "std::abort() -> CRASH"},
    {"LOOP_SYSCALL", kDemoLoopSyscall, nullptr, "the next loop() makes a write() -> SYSCALL"},
    {"SLEEP", kDemoSleep, nullptr, "usleep(2000) -> RUSAGE"}};
inline constexpr CommandInfo kChassisCommands[] = {
    {"MOVE", kChassisMove, &kChassisMoveBody, "drive at vx, vy (m/s), omega (rad/s); only the active pilot"},
    {"SET_ACTIVE_PILOT", kChassisSetActivePilot, &kChassisSetActivePilotBody,
     "only pilot (an address, 0x...) may MOVE; 0 releases"},
    {"GET_PARAMS", kChassisGetParams, nullptr, "the chassis limits (PARAMS reply)"}};
inline constexpr CommandInfo kOdometryCommands[] = {{"RESET", kOdometryReset, nullptr, "the pose to zero"}};
inline constexpr CommandInfo kPositionCommands[] = {
    {"UPDATE", kPositionUpdate, &kPositionUpdateBody, "the robot was at x, y, phi at time_ns (host time)"}};
inline constexpr CommandInfo kMclCommands[] = {
    {"INIT", kMclInit, &kMclInitBody,
     "re-initialise around x, y, phi with sigma_xy (m), sigma_phi (rad); global=1: everywhere"}};
inline constexpr CommandInfo kPathCommands[] = {
    {"MAKE", kPathMake, &kPathMakeBody,
     "a path through count waypoints x=.., y=.. (comma lists); no fields: the parameter"}};
inline constexpr CommandInfo kPilotCommands[] = {
    {"SET_DESTINATION", kPilotSetDestination, &kPilotDestinationBody, "drive straight to x, y (m)"},
    {"FOLLOW_PATH", kPilotFollowPath, nullptr, "follow the Path component's path"},
    {"HOLD", kPilotHold, nullptr, "stop and stand"}};
inline constexpr CommandInfo kServoDriveCommands[] = {
    {"HOME", kServoDriveHome, nullptr, "the current position becomes home"},
    {"MOVE_POS", kServoDriveMovePos, &kServoDriveMovePosBody, "move to position at velocity (0: max)"},
    {"MOVE_VEL", kServoDriveMoveVel, &kServoDriveMoveVelBody, "move at velocity until a limit"}};
inline constexpr DataTypeInfo kScan3d = info<Scan3dData>("Scan3dData", kScan3dNames);
inline constexpr DataTypeInfo kObjRecog = info<ObjRecogData>("ObjRecogData", kObjRecogNames);
inline constexpr DataTypeInfo kScan3dRangeImageRequestBody = info<Scan3dRangeImageRequest>("Scan3dRangeImageRequest");
inline constexpr DataTypeInfo kScan3dStoreDataBody = info<Scan3dStoreData>("Scan3dStoreData");
inline constexpr CommandInfo kScan3dCommands[] = {
    {"GET_RANGE_IMAGE", kScan3dGetRangeImage, &kScan3dRangeImageRequestBody,
     "range image of the newest scan (angular_resolution_deg; none: the parameter)"},
    {"STORE_DATA", kScan3dStoreData, &kScan3dStoreDataBody,
     "write the newest scan as a PCD file (path; none: store_dir)"}};

}  // namespace rack::interfaces::declared
