// Every payload type in both byte orders, decoded as receivers decode it and printed
// as the tools print it: the generic bodies of rack/core/wire.h and every data type
// and command body the classes declare (components/interfaces and each class's
// <class>_types.h).
//
// Input: byte 0 picks the type, byte 1 the mode and byte order (bit 0 set: the body
// is in the other byte order), the rest is the body. Modes:
//   0  decode: read_payload() and read_sample() (rack/core/data_component.h) of the
//      body cut or zero-padded to the type's exact size, the byte order converted back
//      (must give the bytes received), payload_to_json() as rackctl and rack-gui call
//      it (must be valid JSON, RFC 8259), and the type's own check where the tools
//      have one (check_latency_histogram);
//   1  text: set_field_from_text() (rackctl send, set-param) on one field of the type
//      (byte 2 picks it), the text being the rest; a refused text leaves the payload
//      as it was;
//   2  declarations: every class's declared data type and command bodies, as its
//      class description carries them (rack::class_declarations; byte 0 is the class
//      id), and payload_to_json() through them.
// Types larger than 16 KiB (camera frames, 3-D and 2-D scans, range images, paths) are
// printed from the bytes the input has rather than their whole size, which keeps a run
// fast; every field kind and array form is in the smaller types.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fuzz_support.h"
#include "rack/core/data_component.h"
#include "rack/core/payload_json.h"
#include "rack/core/wire.h"
#include "monitor/monitor_types.h"
#include "probe/probe_types.h"
#include "modeswitch_demo/modeswitch_demo_types.h"
#include "evaluator/evaluator_types.h"
#include "pilot/pilot_types.h"
#include "scan3d/scan3d_types.h"
#include "obj_recog/obj_recog_types.h"
#include "gps_nmea/gps_nmea_types.h"
#include "joystick/joystick_types.h"
#include "mcl/mcl_types.h"
#include "rack/components/class_declarations.h"
#include "rack/interfaces/demo.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"
#include "rack/tims/message.h"
#include "rack/tims/payload.h"

namespace {

using rack::fuzz::FuzzInput;
namespace tims = rack::tims;
namespace wire = rack::wire;
namespace ifc = rack::interfaces;

constexpr std::size_t kWholeJsonLimit = 16 * 1024;

// The input cut or zero-padded to `size` bytes.
std::vector<std::byte> exact_body(std::span<const uint8_t> input, std::size_t size) {
  std::vector<std::byte> body(size);
  if (!input.empty()) std::memcpy(body.data(), input.data(), std::min(size, input.size()));
  return body;
}

void check_json(std::span<const tims::FieldDesc> fields, std::span<const std::byte> body, bool native) {
  const std::string j = rack::payload_to_json(fields, body, native);
  FUZZ_CHECK(nlohmann::json::accept(j));
}

template <typename T>
void decode(std::span<const uint8_t> input, bool native) {
  constexpr std::size_t n = sizeof(T);
  const std::vector<std::byte> body = exact_body(input, n);
  auto out = std::make_unique<T>();
  FUZZ_CHECK(wire::read_payload(std::span<const std::byte>(body), native, *out));
  FUZZ_CHECK(!wire::read_payload(std::span<const std::byte>(body).first(n - 1), native, *out));
  // Converting the byte order back gives the bytes received (padding is never touched).
  std::vector<std::byte> back(n);
  std::memcpy(back.data(), out.get(), n);
  if (!native) tims::swap_fields(tims::fields_of<T>, back.data(), n);
  FUZZ_CHECK(back == body);
  // As a DATA message: SampleHeader + T.
  tims::MessageHeader h{};
  h.flags = native ? tims::kNativeFlags : static_cast<uint8_t>(tims::kNativeFlags ^ tims::kFlagBodyLittleEndian);
  const std::vector<std::byte> sample = exact_body(input, sizeof(wire::SampleHeader) + n);
  wire::SampleHeader sh;
  FUZZ_CHECK(rack::read_sample(h, std::span<const std::byte>(sample), sh, *out));
  FUZZ_CHECK(!rack::read_sample(h, std::span<const std::byte>(sample).first(sample.size() - 1), sh, *out));
  // As the tools print it.
  if (n <= kWholeJsonLimit) check_json(tims::fields_of<T>, body, native);
  check_json(tims::fields_of<T>, std::span<const std::byte>(body).first(std::min(n, input.size())), native);
  if constexpr (std::is_same_v<T, wire::LatencyHistogram>) (void)wire::check_latency_histogram(*out);
}

template <typename T>
void set_field(FuzzInput& in) {
  const auto& fields = tims::fields_of<T>;
  const tims::FieldDesc& f = fields[in.byte() % fields.size()];
  const std::span<const uint8_t> rest = in.rest();
  const std::string text(reinterpret_cast<const char*>(rest.data()), rest.size());
  auto payload = std::make_unique<T>();
  std::span<std::byte> bytes(reinterpret_cast<std::byte*>(payload.get()), sizeof(T));
  const std::vector<std::byte> before(bytes.begin(), bytes.end());
  const std::string why = rack::set_field_from_text(f, bytes, text);
  if (!why.empty()) FUZZ_CHECK(std::equal(bytes.begin(), bytes.end(), before.begin()));
  // Whatever was set prints as JSON.
  if (sizeof(T) <= kWholeJsonLimit) check_json(fields, bytes, true);
}

struct TypeOps {
  void (*decode)(std::span<const uint8_t>, bool);
  void (*set_field)(FuzzInput&);
};
template <typename T>
constexpr TypeOps ops() {
  return TypeOps{&decode<T>, &set_field<T>};
}

constexpr TypeOps kTypes[] = {
    // rack/core/wire.h
    ops<wire::GetDataRequest>(), ops<wire::ContDataRequest>(), ops<wire::ContDataReply>(),
    ops<wire::StopContDataRequest>(), ops<wire::SampleHeader>(), ops<wire::ErrorText>(), ops<wire::ParamName>(),
    ops<wire::ParamRecord>(), ops<wire::StatsReply>(), ops<wire::LatencyHistogram>(),
    // components/interfaces
    ops<ifc::GeneratorData>(), ops<ifc::MonitorData>(), ops<ifc::ProbeData>(), ops<ifc::ModeSwitchDemoData>(),
    ops<ifc::GpsData>(), ops<ifc::JoystickData>(), ops<ifc::ServoDriveData>(), ops<ifc::ServoDriveMovePos>(),
    ops<ifc::ServoDriveMoveVel>(), ops<ifc::CameraData>(), ops<ifc::EvaluatorData>(), ops<ifc::PathData>(),
    ops<ifc::PathMake>(), ops<ifc::PilotData>(), ops<ifc::PilotDestination>(), ops<ifc::Scan3dData>(),
    ops<ifc::Scan3dRangeImageRequest>(), ops<ifc::Scan3dRangeImage>(), ops<ifc::Scan3dStoreData>(),
    ops<ifc::ObjRecogData>(), ops<ifc::ChassisData>(), ops<ifc::ChassisMove>(), ops<ifc::ChassisSetActivePilot>(),
    ops<ifc::ChassisParams>(), ops<ifc::LadarData>(), ops<ifc::OdometryData>(), ops<ifc::PositionData>(),
    ops<ifc::PositionUpdate>(), ops<ifc::Scan2dData>(), ops<ifc::MclData>(), ops<ifc::MclInit>()};
constexpr std::size_t kTypeCount = sizeof kTypes / sizeof kTypes[0];

void through_declarations(uint8_t class_id, std::span<const uint8_t> input, bool native) {
  for (const rack::components::ClassDeclaration& d : rack::components::class_declarations()) {
    if (d.class_id != class_id) continue;
    if (const rack::DataTypeInfo* t = d.data) {
      const std::vector<std::byte> body = exact_body(input, t->size);
      if (t->size <= kWholeJsonLimit) check_json(t->fields, body, native);
      check_json(t->fields, std::span<const std::byte>(body).first(std::min<std::size_t>(t->size, input.size())),
                 native);
    }
    for (const rack::CommandInfo& c : d.commands) {
      FUZZ_CHECK(c.name != nullptr && c.type > 0);
      if (c.body != nullptr) check_json(c.body->fields, exact_body(input, c.body->size), native);
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  const uint8_t selector = in.byte();
  const uint8_t mode = in.byte();
  const bool native = (mode & 1) == 0;
  switch ((mode >> 1) % 3) {
    case 0: kTypes[selector % kTypeCount].decode(in.rest(), native); break;
    case 1: kTypes[selector % kTypeCount].set_field(in); break;
    default: through_declarations(selector, in.rest(), native); break;
  }
  return 0;
}
