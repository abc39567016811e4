// rack-gui's WebSocket messages (tools/gui/gui_protocol.cpp): whatever a browser, or
// anything else that reaches the port, sends as one text message.
//
// Input: the message's bytes, as HttpServer hands them over (any bytes: the server
// passes text frames on without checking their UTF-8). Checked:
//  - parse_request() returns (never throws, never ends the process);
//  - a refusal has a reason in range and a message of bounded length, and the error
//    message the server sends is valid JSON carrying both;
//  - an accepted request holds to the protocol's limits: a known op, a system number
//    0..254, a component's command mailbox, finite numbers within their bounds, a
//    parameter name of 1..kParamNameLen-1 bytes and a primitive value; its result
//    message is valid JSON;
//  - a set_param value, checked against every parameter kind (check_param_value), is
//    either refused with a reason or stored within the record (NUL-terminated text,
//    finite float);
//  - a command body (encode_command_body) against a type with every field kind: refused
//    with a bounded reason, or exactly the type's size; against no type, accepted only
//    when empty.
//
// Build (until tests/fuzz/CMakeLists.txt lists it: rack_fuzz_harness(gui_ws LIBRARIES
// rack_gui_backend)) and run by hand, from the repository root, as one command line:
//   clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
//     -Itools/gui -Itims/include -Icore/include -Icore/rt/include
//     tests/fuzz/fuzz_gui_ws.cpp tools/gui/gui_protocol.cpp
//     tims/src/address.cpp core/src/payload_json.cpp core/src/class_description.cpp -o /tmp/fuzz_gui_ws
//   mkdir -p /tmp/gui_ws_corpus
//   /tmp/fuzz_gui_ws -max_len=70000 -max_total_time=300 /tmp/gui_ws_corpus tests/fuzz/corpus/gui_ws
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "gui_protocol.h"

namespace gui = rack::gui;
namespace wire = rack::wire;

namespace {

// Aborts with file:line when a property does not hold (a crash libFuzzer keeps).
#define GUI_WS_CHECK(cond)                                                               \
  do {                                                                                   \
    if (!(cond)) {                                                                       \
      std::fprintf(stderr, "%s:%d: fuzz check failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                      \
    }                                                                                    \
  } while (0)

// A command body type with a field of every kind (scalars, an array, a text).
const rack::TypeDescription& command_type() {
  static const rack::TypeDescription kType = [] {
    rack::TypeDescription t;
    t.name = "FuzzBody";
    using K = rack::tims::FieldKind;
    uint32_t offset = 0;
    const auto add = [&](const char* name, K kind, uint32_t count) {
      t.fields.push_back({name, kind, offset, count, ""});
      offset += rack::tims::field_kind_size(kind) * count;
    };
    add("f64", K::kF64, 1);
    add("i64", K::kI64, 1);
    add("u64", K::kU64, 1);
    add("f32s", K::kF32, 8);
    add("i32", K::kI32, 1);
    add("u32", K::kU32, 1);
    add("i16", K::kI16, 1);
    add("u16", K::kU16, 1);
    add("i8", K::kI8, 1);
    add("u8", K::kU8, 1);
    add("flag", K::kBool, 1);
    add("text", K::kChar, 16);
    t.size = offset;
    return t;
  }();
  return kType;
}

bool within(double v, double limit) { return std::isfinite(v) && std::fabs(v) <= limit; }

void check_refusal(const gui::ParseError& e) {
  GUI_WS_CHECK(static_cast<std::size_t>(e.reason) < gui::kRefusalKinds);
  GUI_WS_CHECK(!e.message.empty());
  // Quoted client texts are cut to kMaxQuoted: the message stays short whatever came in.
  GUI_WS_CHECK(e.message.size() <= 1024);
  const std::string out = gui::error_message(e);
  GUI_WS_CHECK(nlohmann::json::accept(out));
  const auto j = nlohmann::json::parse(out);
  GUI_WS_CHECK(j.at("type") == "error");
  GUI_WS_CHECK(j.at("reason") == gui::describe(e.reason));
}

void check_value_against_kinds(const nlohmann::json& value) {
  for (const auto kind :
       {wire::ParamKind::kInt, wire::ParamKind::kFloat, wire::ParamKind::kBool, wire::ParamKind::kString}) {
    wire::ParamRecord p{};
    p.kind = static_cast<decltype(p.kind)>(kind);
    const std::string why = gui::check_param_value(value, p);
    if (!why.empty()) continue;
    switch (kind) {
      case wire::ParamKind::kFloat: GUI_WS_CHECK(std::isfinite(p.float_value)); break;
      case wire::ParamKind::kBool: GUI_WS_CHECK(p.int_value == 0 || p.int_value == 1); break;
      case wire::ParamKind::kString:
        GUI_WS_CHECK(std::memchr(p.string_value, '\0', sizeof p.string_value) != nullptr);
        break;
      case wire::ParamKind::kInt: break;
    }
  }
}

void check_request(const gui::Request& r) {
  GUI_WS_CHECK(std::string(gui::op_name(r.op)) != "?");
  switch (r.op) {
    case gui::Op::kSwitch:
    case gui::Op::kGetParams: GUI_WS_CHECK(r.component.mailbox() == 0); break;
    case gui::Op::kSetParam:
      GUI_WS_CHECK(r.component.mailbox() == 0);
      GUI_WS_CHECK(!r.param_name.empty() && r.param_name.size() < wire::kParamNameLen);
      GUI_WS_CHECK(r.param_value.is_primitive() && !r.param_value.is_null());
      check_value_against_kinds(r.param_value);
      break;
    case gui::Op::kSetDestination:
      GUI_WS_CHECK(within(r.x, gui::kMaxCoordinate) && within(r.y, gui::kMaxCoordinate));
      break;
    case gui::Op::kSetPose:
      GUI_WS_CHECK(within(r.x, gui::kMaxCoordinate) && within(r.y, gui::kMaxCoordinate));
      GUI_WS_CHECK(within(r.phi, 4.0 * M_PI));
      break;
    case gui::Op::kJoystick:
      GUI_WS_CHECK(within(r.vx, gui::kMaxJoystickSpeed) && within(r.omega, gui::kMaxJoystickOmega));
      break;
    case gui::Op::kAllOff:
    case gui::Op::kJoystickRelease:
    case gui::Op::kFollowPath: break;
    case gui::Op::kGetClass:
    case gui::Op::kUnsubscribe: GUI_WS_CHECK(r.component.mailbox() == 0); break;
    case gui::Op::kSubscribe:
      GUI_WS_CHECK(r.component.mailbox() == 0);
      GUI_WS_CHECK(r.period_ms >= 0.0 && r.period_ms <= gui::kMaxStreamPeriodMs);
      break;
    case gui::Op::kCommand:
      GUI_WS_CHECK(r.component.mailbox() == 0);
      GUI_WS_CHECK(!r.command_name.empty() && r.command_name.size() <= gui::kMaxFieldName);
      GUI_WS_CHECK(r.fields.size() <= gui::kMaxCommandFields);
      for (const auto& [name, value] : r.fields) {
        GUI_WS_CHECK(!name.empty() && name.size() <= gui::kMaxFieldName);
        GUI_WS_CHECK(value.size() <= gui::kMaxFieldText);
      }
      break;
    case gui::Op::kTrace:
      GUI_WS_CHECK(r.duration_s > 0.0 && r.duration_s <= gui::kMaxTraceSeconds);
      GUI_WS_CHECK(r.host.size() <= gui::kMaxFieldName);
      break;
    case gui::Op::kCommandJson: {
      GUI_WS_CHECK(r.component.mailbox() == 0);
      GUI_WS_CHECK(!r.command.empty() && r.command.size() <= gui::kMaxCommandName);
      GUI_WS_CHECK(r.body.is_object());
      // The body against a type with every kind of field, and against none: refused
      // with a reason or encoded to exactly the type's size.
      std::vector<std::byte> out;
      const std::string why = gui::encode_command_body(r.body, &command_type(), out);
      GUI_WS_CHECK(why.size() <= 1024);
      if (why.empty()) GUI_WS_CHECK(out.size() == command_type().size);
      const std::string none = gui::encode_command_body(r.body, nullptr, out);
      GUI_WS_CHECK(none.empty() == r.body.empty());
      break;
    }
  }
  GUI_WS_CHECK(r.system <= 254);
  GUI_WS_CHECK(nlohmann::json::accept(gui::result_message(r.id, r.op, true, "done")));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto parsed = gui::parse_request(text);
  if (const auto* e = std::get_if<gui::ParseError>(&parsed)) {
    check_refusal(*e);
    if (size > gui::kMaxRequestBytes) GUI_WS_CHECK(e->reason == gui::Refusal::kTooLarge);
  } else {
    GUI_WS_CHECK(size <= gui::kMaxRequestBytes);
    check_request(std::get<gui::Request>(parsed));
  }
  return 0;
}
