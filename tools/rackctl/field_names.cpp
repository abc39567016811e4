#include "field_names.h"

#include <array>
#include <cstring>
#include <string_view>

#include "rack/core/payload_json.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/perception.h"
#include "rack/tims/address.h"

namespace rack::tools {
namespace {

namespace cls = tims::classes;

struct EnumValue {
  uint32_t value;
  const char* name;
};
struct EnumField {
  uint8_t class_id;
  const char* field;
  std::span<const EnumValue> values;
};

using interfaces::PilotMode;
using interfaces::PilotStatus;
constexpr uint32_t u(PilotMode m) { return static_cast<uint32_t>(m); }
constexpr uint32_t u(PilotStatus s) { return static_cast<uint32_t>(s); }

// The values as the interface headers define them (the constants, not copies).
constexpr EnumValue kPilotModes[] = {
    {u(PilotMode::kHold), "HOLD"}, {u(PilotMode::kFollowPath), "FOLLOW_PATH"}, {u(PilotMode::kDestination), "DESTINATION"}};
constexpr EnumValue kPilotStatuses[] = {
    {u(PilotStatus::kIdle), "IDLE"},         {u(PilotStatus::kDriving), "DRIVING"},
    {u(PilotStatus::kReached), "REACHED"},   {u(PilotStatus::kBlocked), "BLOCKED"},
    {u(PilotStatus::kNoPath), "NO_PATH"},    {u(PilotStatus::kPreempted), "PREEMPTED"},
    {u(PilotStatus::kNoInput), "NO_INPUT"},  {u(PilotStatus::kPlanning), "PLANNING"},
    {u(PilotStatus::kUnreachable), "UNREACHABLE"}};
constexpr EnumValue kGpsFixQualities[] = {{interfaces::kGpsFixNone, "NONE"},
                                          {interfaces::kGpsFixGps, "GPS"},
                                          {interfaces::kGpsFixDgps, "DGPS"},
                                          {interfaces::kGpsFixRtkFixed, "RTK_FIXED"},
                                          {interfaces::kGpsFixRtkFloat, "RTK_FLOAT"}};
constexpr EnumValue kGpsFixModes[] = {{1, "NONE"}, {2, "2D"}, {3, "3D"}};  // GSA's mode (devices.h)
constexpr EnumValue kCameraFormats[] = {
    {interfaces::kCameraRgb8, "RGB8"}, {interfaces::kCameraMono8, "MONO8"}, {interfaces::kCameraJpeg, "JPEG"}};
constexpr EnumValue kScan3dModes[] = {{interfaces::kScan3dModeRoll, "ROLL"},
                                      {interfaces::kScan3dModePitch, "PITCH"},
                                      {interfaces::kScan3dModeYaw, "YAW"},
                                      {interfaces::kScan3dModeFile, "FILE"}};
constexpr EnumValue kObjFrames[] = {{interfaces::kObjFrameCamera, "CAMERA"}, {interfaces::kObjFrameRobot, "ROBOT"}};

constexpr EnumField kEnumFields[] = {
    {cls::kPilot, "mode", kPilotModes},         {cls::kPilot, "status", kPilotStatuses},
    {cls::kGps, "fix_quality", kGpsFixQualities}, {cls::kGps, "fix_mode", kGpsFixModes},
    {cls::kCamera, "format", kCameraFormats},   {cls::kScan3d, "mode", kScan3dModes},
    {cls::kObjRecog, "frame", kObjFrames},
};

// Fields that hold a raw tims::Address (0: none), by class.
struct AddressField {
  uint8_t class_id;
  const char* field;
};
constexpr AddressField kAddressFields[] = {{cls::kChassis, "active_pilot"}};  // named as its component

const EnumField* enum_field(uint8_t class_id, std::string_view field) {
  for (const auto& e : kEnumFields) {
    if (e.class_id == class_id && field == e.field) return &e;
  }
  return nullptr;
}
bool address_field(uint8_t class_id, std::string_view field) {
  for (const auto& a : kAddressFields) {
    if (a.class_id == class_id && field == a.field) return true;
  }
  return false;
}

// An unsigned scalar field of up to 4 bytes, in host order; false when out of the sample.
bool read_unsigned(const tims::FieldDesc& f, std::span<const std::byte> sample, bool native, uint32_t& out) {
  const uint32_t size = tims::field_kind_size(f.kind);
  if (f.count != 1 || size > 4 || f.offset > sample.size() || sample.size() - f.offset < size) return false;
  std::array<unsigned char, 4> b{};
  std::memcpy(b.data(), sample.data() + f.offset, size);
  if (!native && size > 1) {
    for (uint32_t i = 0; i < size / 2; ++i) std::swap(b[i], b[size - 1 - i]);
  }
  switch (size) {
    case 1: out = b[0]; return true;
    case 2: {
      uint16_t v = 0;
      std::memcpy(&v, b.data(), 2);
      out = v;
      return true;
    }
    default: {
      std::memcpy(&out, b.data(), 4);
      return true;
    }
  }
}

}  // namespace

const char* enum_value_name(uint8_t class_id, const std::string& field, uint32_t v) {
  const EnumField* e = enum_field(class_id, field);
  if (e == nullptr) return nullptr;
  for (const auto& ev : e->values) {
    if (ev.value == v) return ev.name;
  }
  return nullptr;
}

std::string field_names_json(uint8_t class_id, std::span<const tims::FieldDesc> fields,
                             std::span<const std::byte> sample, bool native) {
  std::string out;
  for (const auto& f : fields) {
    const bool is_enum = enum_field(class_id, f.name) != nullptr;
    const bool is_address = address_field(class_id, f.name);
    if (!is_enum && !is_address) continue;
    uint32_t v = 0;
    if (!read_unsigned(f, sample, native, v)) continue;
    std::string name;
    if (is_address) {
      name = v == 0 ? "none" : tims::Address(v).component().str();  // the component, not its mailbox
    } else if (const char* n = enum_value_name(class_id, f.name, v)) {
      name = n;
    } else {
      name = "UNKNOWN(" + std::to_string(v) + ")";
    }
    out += (out.empty() ? "{\"" : ",\"") + rack::json_escape(f.name) + "\":\"" + rack::json_escape(name) + "\"";
  }
  return out.empty() ? out : out + "}";
}

}  // namespace rack::tools
