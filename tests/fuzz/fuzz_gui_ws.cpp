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
//    finite float).
//
// Build (until tests/fuzz/CMakeLists.txt lists it: rack_fuzz_harness(gui_ws LIBRARIES
// rack_gui_backend)) and run by hand, from the repository root, as one command line:
//   clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
//     -Itools/gui -Itims/include -Icore/include -Icore/rt/include
//     tests/fuzz/fuzz_gui_ws.cpp tools/gui/gui_protocol.cpp tims/src/address.cpp -o /tmp/fuzz_gui_ws
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

#include <nlohmann/json.hpp>

#include "gui_protocol.h"

namespace gui = rack::gui;
namespace wire = rack::wire;

namespace {

// Aborts with file:line when a property does not hold (a crash libFuzzer keeps).
#define GUI_WS_CHECK(cond)                                                           \
  do {                                                                               \
    if (!(cond)) {                                                                   \
      std::fprintf(stderr, "%s:%d: fuzz check failed: %s\n", __FILE__, __LINE__, #cond); \
      std::abort();                                                                  \
    }                                                                                \
  } while (0)

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
  for (const auto kind : {wire::ParamKind::kInt, wire::ParamKind::kFloat, wire::ParamKind::kBool,
                          wire::ParamKind::kString}) {
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
    case gui::Op::kGetClass: GUI_WS_CHECK(r.component.mailbox() == 0); break;
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
