#include "rack/interfaces/data_types.h"

#include "rack/interfaces/demo.h"
#include "rack/interfaces/evaluation.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/perception.h"
#include "rack/interfaces/robot.h"
#include "rack/tims/address.h"

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
constexpr DataTypeInfo kScan3d = info<Scan3dData>("Scan3dData");
constexpr DataTypeInfo kObjRecog = info<ObjRecogData>("ObjRecogData");
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

}  // namespace rack::interfaces
