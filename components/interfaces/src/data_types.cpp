#include "rack/interfaces/data_types.h"

#include "rack/interfaces/demo.h"
#include "rack/interfaces/evaluation.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/perception.h"
#include "rack/interfaces/robot.h"
#include "rack/tims/address.h"

#include <array>

namespace rack::interfaces {

namespace {
template <typename T>
constexpr DataTypeInfo info(const char* name) {
  return DataTypeInfo{name, sizeof(T), std::span<const tims::FieldDesc>(tims::fields_of<T>)};
}
constexpr DataTypeInfo kGenerator = info<GeneratorData>("GeneratorData");
constexpr DataTypeInfo kMonitor = info<MonitorData>("MonitorData");
constexpr DataTypeInfo kProbe = info<ProbeData>("ProbeData");
constexpr DataTypeInfo kChassis = info<ChassisData>("ChassisData");
constexpr DataTypeInfo kLadar = info<LadarData>("LadarData");
constexpr DataTypeInfo kOdometry = info<OdometryData>("OdometryData");
constexpr DataTypeInfo kPosition = info<PositionData>("PositionData");
constexpr DataTypeInfo kScan2d = info<Scan2dData>("Scan2dData");
constexpr DataTypeInfo kMcl = info<MclData>("MclData");
constexpr DataTypeInfo kPath = info<PathData>("PathData");
constexpr DataTypeInfo kPilot = info<PilotData>("PilotData");
constexpr DataTypeInfo kEvaluator = info<EvaluatorData>("EvaluatorData");
constexpr DataTypeInfo kModeSwitchDemo = info<ModeSwitchDemoData>("ModeSwitchDemoData");
constexpr DataTypeInfo kGps = info<GpsData>("GpsData");
constexpr DataTypeInfo kJoystick = info<JoystickData>("JoystickData");
constexpr DataTypeInfo kServoDrive = info<ServoDriveData>("ServoDriveData");
constexpr DataTypeInfo kCamera = info<CameraData>("CameraData");

// Bodies of class commands.
struct Int64Body {  // the 8-byte integer body of Probe ECHO and ModeSwitchDemo SPIN
  int64_t value = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(Int64Body, value)}; }
};
constexpr DataTypeInfo kInt64Body = info<Int64Body>("Int64");
constexpr DataTypeInfo kChassisMoveBody = info<ChassisMove>("ChassisMove");
constexpr DataTypeInfo kChassisSetActivePilotBody = info<ChassisSetActivePilot>("ChassisSetActivePilot");
constexpr DataTypeInfo kPositionUpdateBody = info<PositionUpdate>("PositionUpdate");
constexpr DataTypeInfo kMclInitBody = info<MclInit>("MclInit");
constexpr DataTypeInfo kPathMakeBody = info<PathMake>("PathMake");
constexpr DataTypeInfo kPilotDestinationBody = info<PilotDestination>("PilotDestination");
constexpr DataTypeInfo kServoDriveMovePosBody = info<ServoDriveMovePos>("ServoDriveMovePos");
constexpr DataTypeInfo kServoDriveMoveVelBody = info<ServoDriveMoveVel>("ServoDriveMoveVel");

constexpr CommandInfo kGeneratorCommands[] = {
    {"RESET", kGeneratorReset, nullptr, "the counter to 0"}};
constexpr CommandInfo kProbeCommands[] = {
    {"ECHO", kProbeEcho, &kInt64Body, "replies OK with the same body"},
    {"THROW", kProbeThrow, nullptr, "command() throws: the component goes to ERROR"}};
constexpr CommandInfo kModeSwitchDemoCommands[] = {
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
constexpr CommandInfo kChassisCommands[] = {
    {"MOVE", kChassisMove, &kChassisMoveBody, "drive at vx, vy (m/s), omega (rad/s); only the active pilot"},
    {"SET_ACTIVE_PILOT", kChassisSetActivePilot, &kChassisSetActivePilotBody,
     "only pilot (an address, 0x...) may MOVE; 0 releases"},
    {"GET_PARAMS", kChassisGetParams, nullptr, "the chassis limits (PARAMS reply)"}};
constexpr CommandInfo kOdometryCommands[] = {{"RESET", kOdometryReset, nullptr, "the pose to zero"}};
constexpr CommandInfo kPositionCommands[] = {
    {"UPDATE", kPositionUpdate, &kPositionUpdateBody, "the robot was at x, y, phi at time_ns (host time)"}};
constexpr CommandInfo kMclCommands[] = {
    {"INIT", kMclInit, &kMclInitBody,
     "re-initialise around x, y, phi with sigma_xy (m), sigma_phi (rad); global=1: everywhere"}};
constexpr CommandInfo kPathCommands[] = {
    {"MAKE", kPathMake, &kPathMakeBody, "a path through count waypoints x=.., y=.. (comma lists); no fields: the parameter"}};
constexpr CommandInfo kPilotCommands[] = {
    {"SET_DESTINATION", kPilotSetDestination, &kPilotDestinationBody, "drive straight to x, y (m)"},
    {"FOLLOW_PATH", kPilotFollowPath, nullptr, "follow the Path component's path"},
    {"HOLD", kPilotHold, nullptr, "stop and stand"}};
constexpr CommandInfo kServoDriveCommands[] = {
    {"HOME", kServoDriveHome, nullptr, "the current position becomes home"},
    {"MOVE_POS", kServoDriveMovePos, &kServoDriveMovePosBody, "move to position at velocity (0: max)"},
    {"MOVE_VEL", kServoDriveMoveVel, &kServoDriveMoveVelBody, "move at velocity until a limit"}};
constexpr DataTypeInfo kScan3d = info<Scan3dData>("Scan3dData");
constexpr DataTypeInfo kObjRecog = info<ObjRecogData>("ObjRecogData");
constexpr DataTypeInfo kScan3dRangeImageRequestBody = info<Scan3dRangeImageRequest>("Scan3dRangeImageRequest");
constexpr DataTypeInfo kScan3dStoreDataBody = info<Scan3dStoreData>("Scan3dStoreData");
constexpr CommandInfo kScan3dCommands[] = {
    {"GET_RANGE_IMAGE", kScan3dGetRangeImage, &kScan3dRangeImageRequestBody,
     "range image of the newest scan (angular_resolution_deg; none: the parameter)"},
    {"STORE_DATA", kScan3dStoreData, &kScan3dStoreDataBody, "write the newest scan as a PCD file (path; none: store_dir)"}};
}  // namespace

const DataTypeInfo* data_type_for_class(uint8_t class_id) noexcept {
  switch (class_id) {
    case tims::classes::kGenerator: return &kGenerator;
    case tims::classes::kMonitor: return &kMonitor;
    case tims::classes::kProbe: return &kProbe;
    case tims::classes::kChassis: return &kChassis;
    case tims::classes::kLadar: return &kLadar;
    case tims::classes::kOdometry: return &kOdometry;
    case tims::classes::kPosition: return &kPosition;
    case tims::classes::kScan2d: return &kScan2d;
    case tims::classes::kMcl: return &kMcl;
    case tims::classes::kPath: return &kPath;
    case tims::classes::kPilot: return &kPilot;
    case tims::classes::kEvaluator: return &kEvaluator;
    case tims::classes::kModeSwitchDemo: return &kModeSwitchDemo;
    case tims::classes::kGps: return &kGps;
    case tims::classes::kJoystick: return &kJoystick;
    case tims::classes::kServoDrive: return &kServoDrive;
    case tims::classes::kCamera: return &kCamera;
    case tims::classes::kScan3d: return &kScan3d;
    case tims::classes::kObjRecog: return &kObjRecog;
    default: return nullptr;
  }
}

std::span<const CommandInfo> commands_for_class(uint8_t class_id) noexcept {
  switch (class_id) {
    case tims::classes::kGenerator: return kGeneratorCommands;
    case tims::classes::kProbe: return kProbeCommands;
    case tims::classes::kModeSwitchDemo: return kModeSwitchDemoCommands;
    case tims::classes::kChassis: return kChassisCommands;
    case tims::classes::kOdometry: return kOdometryCommands;
    case tims::classes::kPosition: return kPositionCommands;
    case tims::classes::kMcl: return kMclCommands;
    case tims::classes::kPath: return kPathCommands;
    case tims::classes::kPilot: return kPilotCommands;
    case tims::classes::kServoDrive: return kServoDriveCommands;
    case tims::classes::kScan3d: return kScan3dCommands;
    default: return {};
  }
}

}  // namespace rack::interfaces
