#include "rack/interfaces/data_types.h"

#include "rack/interfaces/demo.h"
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
constexpr DataTypeInfo kModeSwitchDemo = info<ModeSwitchDemoData>("ModeSwitchDemoData");
}  // namespace

const DataTypeInfo* data_type_for_class(uint8_t class_id) noexcept {
  switch (class_id) {
    case tims::classes::kGenerator: return &kGenerator;
    case tims::classes::kMonitor: return &kMonitor;
    case tims::classes::kProbe: return &kProbe;
    case tims::classes::kModeSwitchDemo: return &kModeSwitchDemo;
    default: return nullptr;
  }
}

}  // namespace rack::interfaces
