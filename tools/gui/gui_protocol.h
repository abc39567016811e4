// rack-gui's WebSocket protocol: what the browser may ask for, parsed and checked
// strictly before anything is sent to a robot.
//
// Client -> server: one JSON object per WebSocket text message, with "op" and an
// optional integer "id" that the server echoes in its "result" message:
//
//   {"op":"switch","component":"Chassis(0/0)","on":true}
//   {"op":"all_off","system":0}                       every component of robot 0, reverse order
//   {"op":"get_params","component":"Pilot(0/0)"}
//   {"op":"set_param","component":"Pilot(0/0)","name":"vx_max","value":0.5}
//   {"op":"set_destination","system":0,"x":10.0,"y":8.0}      Pilot SET_DESTINATION
//   {"op":"set_pose","system":0,"x":4.0,"y":7.2,"phi":0.0}   Position UPDATE + MCL INIT
//   {"op":"joystick","system":0,"vx":0.3,"omega":0.0}        become the active pilot, MOVE
//   {"op":"joystick_release","system":0}                     MOVE 0 (dead-man released)
//   {"op":"follow_path","system":0}                          hand the chassis back to the Pilot
//   {"op":"get_class","component":"Pilot(0/0)"}              its class description (GET_CLASS)
//   {"op":"command","component":"Pilot(0/0)","name":"SET_DESTINATION","fields":{"x":"2.5","y":1}}
//       a class command by the name its class describes; "fields" (at most
//       kMaxCommandFields, names < kMaxFieldName bytes, values texts, numbers or
//       booleans) fill its body as `rackctl send` does; fields not given are 0
//   {"op":"trace","system":0,"host":"","duration_s":2}   a live task timeline of one
//       host of robot 0 (as `rackctl trace --duration 2 all`; "" = its only host),
//       answered with {"type":"trace",...}; duration 0 < s <= kMaxTraceSeconds
//   {"op":"command_json","component":"MCL(0/0)","command":"INIT","body":{"x":4.0,"y":7.2}}
//        any command (as "command", but typed: for programs such as the
//        Foxglove bridge) of the component's class by its name in the class description, the
//        body's fields by name (a field left out is 0; arrays as JSON arrays, char
//        arrays as strings), checked against the description's field kinds and ranges
//        (encode_command_body) before anything is sent
//   {"op":"subscribe","component":"Scan2D(0/0)","period_ms":0}   the component's data
//        stream (GET_CONT_DATA): every sample ("period_ms" 0 or left out) or one per
//        period (0 < period_ms <= kMaxStreamPeriodMs, rounded by the producer to a
//        multiple of its own), each as a "data" message with "stream":true to the
//        clients that subscribed (not to the others); kept while the component is
//        off or gone and taken up again when it is enabled
//   {"op":"unsubscribe","component":"Scan2D(0/0)"}   ends this client's subscription
//
// Anything else is refused with a ParseError saying what and where (a byte offset for
// JSON syntax, the key otherwise) and why (Refusal, which the server counts); the
// caller answers {"type":"error",...} and sends nothing to any robot: a message over
// kMaxRequestBytes, not JSON or not UTF-8, nested deeper than kMaxRequestDepth, a key
// given twice in one object, not an object, an unknown op or key, a missing key, a
// value of the wrong JSON type, an integer outside its range (never wrapped), a number
// out of range or not finite, a text that is not a component address. Texts from the
// message that a refusal quotes are cut to kMaxQuoted bytes.
//
// parse_request is total: it never throws and never ends the process, whatever the
// bytes (tests/fuzz/fuzz_gui_ws.cpp drives it with arbitrary input).
//
// Whether a parameter VALUE has the right type for the parameter's kind is checked
// against the kind the component reports (check_param_value), since only the component
// knows it.
//
// Not RT code (a tool). Thread-safety: free functions, no shared state.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "rack/core/class_description.h"
#include "rack/core/wire.h"
#include "rack/tims/address.h"

namespace rack::gui {

enum class Op {
  kSwitch,
  kAllOff,
  kGetParams,
  kSetParam,
  kSetDestination,
  kSetPose,
  kJoystick,
  kJoystickRelease,
  kFollowPath,
  kGetClass,
  kCommand,
  kTrace,
  kCommandJson,
  kSubscribe,
  kUnsubscribe,
};
[[nodiscard]] const char* op_name(Op op) noexcept;

// Limits of a client message (the server refuses a larger WebSocket message before
// it is read: HttpServer::kMaxMessage is this).
inline constexpr std::size_t kMaxRequestBytes = 64 * 1024;
inline constexpr int kMaxRequestDepth = 8;     // objects and arrays inside each other
inline constexpr std::size_t kMaxQuoted = 64;  // bytes of a client's text quoted back

// Limits a browser may ask for; the chassis clamps to its own limits as well.
inline constexpr double kMaxJoystickSpeed = 5.0;       // m/s
inline constexpr double kMaxJoystickOmega = 10.0;      // rad/s
inline constexpr double kMaxCoordinate = 1.0e6;        // m: anything larger is a mistake
inline constexpr std::size_t kMaxCommandFields = 64;   // "fields" of a command
inline constexpr std::size_t kMaxFieldName = 64;       // bytes of a field name
inline constexpr std::size_t kMaxFieldText = 4096;     // bytes of a field's value text
inline constexpr double kMaxTraceSeconds = 10.0;       // a live trace from the dashboard
inline constexpr double kMaxStreamPeriodMs = 60000.0;  // "period_ms" of a subscription

struct Request {
  Op op = Op::kSwitch;
  std::optional<int64_t> id;  // echoed in the result
  tims::Address component;    // switch, get_params, set_param (command mailbox)
  // The class name of `component` when TiMS does not know it (a component class:
  // Chassis(0/0), Counter(2/0)); `component` then has class id 0 and the backend
  // finds the component by the name its class describes. Empty: `component` is whole.
  std::string component_class;
  uint8_t system = 0;                                       // robot-wide ops
  bool on = false;                                          // switch
  std::string param_name;                                   // set_param
  nlohmann::json param_value;                               // set_param: checked against the kind later
  double x = 0.0, y = 0.0, phi = 0.0;                       // set_destination, set_pose
  double vx = 0.0, omega = 0.0;                             // joystick
  std::string command_name;                                 // command: the name its class describes
  std::vector<std::pair<std::string, std::string>> fields;  // command: field -> value text
  std::string host;                                         // trace: the host's name ("" = the robot's only host)
  double duration_s = 0.0;                                  // trace
  std::string command;                                      // command: the class command's name (upper case)
  nlohmann::json body;                                      // command: an object of field values, checked later
  double period_ms = 0.0;                                   // subscribe: 0 = every sample
};

// Why a client message was refused (counted per reason by the server).
enum class Refusal : uint8_t {
  kTooLarge,      // over kMaxRequestBytes
  kNotJson,       // JSON syntax, invalid UTF-8, a number JSON cannot hold
  kTooDeep,       // nested deeper than kMaxRequestDepth
  kDuplicateKey,  // a key twice in one object
  kNotObject,     // valid JSON, but not an object
  kBadOp,         // "op" missing, not a string, or unknown
  kBadKey,        // a key the op does not take, or a required key missing
  kBadValue,      // a value of the wrong type or out of range ("id" included)
  kBusy,          // (server) too many requests waiting for the robots
  kBinary,        // (server) a binary WebSocket message
};
inline constexpr std::size_t kRefusalKinds = 10;
[[nodiscard]] const char* describe(Refusal r) noexcept;

struct ParseError {
  std::optional<int64_t> id;  // when the message had a readable id
  std::string message;        // what and where ("key 'x': expected a number, got string")
  Refusal reason = Refusal::kNotJson;
};

// Parses and validates one client message (any bytes). Never throws.
[[nodiscard]] std::variant<Request, ParseError> parse_request(std::string_view text) noexcept;

// Fills `record`'s value from a JSON value when it has the type of the record's kind
// (int: an integer; float: a finite number; bool: true/false; string: a string shorter
// than wire::kParamStringLen). Returns the problem, or "" when it was set.
[[nodiscard]] std::string check_param_value(const nlohmann::json& value, wire::ParamRecord& record);

// Longest class command name a client may give (the descriptions' names are shorter).
inline constexpr std::size_t kMaxCommandName = 31;

// A command's body from the JSON object of a "command" request: `out` becomes
// `type.size` bytes (host byte order), zero but for the fields `body` names; each value
// must fit its field (rack::set_field_from_text: kind, range, array length, string
// length). Returns the problem naming the field ("field 'x': ..."), or "" when `out`
// holds the body. `type` nullptr: the command takes no body, and `body` must be empty.
// Never throws.
[[nodiscard]] std::string encode_command_body(const nlohmann::json& body, const rack::TypeDescription* type,
                                              std::vector<std::byte>& out) noexcept;

// Server -> client helpers.
//
// A component's wake-up latency histogram, from its LATENCY reply (GET_LATENCY, polled
// with GET_STATS), as the "latency" key of the component in the "components" message:
//
//   {"data_task":1,"period_ns":10000000,"cycles":500,"overruns":0,"samples":499,
//    "latency_ns":{"min":..,"p50":..,"p99":..,"p999":..,"max":..,"mean":..},
//    "lower_ns":[0,1000,...,10000000],"counts":[0,12,...,0]}
//
// lower_ns[j] is bucket j's lower edge; bucket j ends where j+1 starts, the last is
// open; both arrays have the reply's bucket_count entries and the counts add up to
// samples. A reply that breaks this (wire::check_latency_histogram) gives the reason
// instead, and the server passes nothing on.
[[nodiscard]] std::variant<nlohmann::json, std::string> latency_json(const wire::LatencyHistogram& h);

[[nodiscard]] std::string error_message(const ParseError& e);
[[nodiscard]] std::string result_message(const std::optional<int64_t>& id, Op op, bool ok, const std::string& text);

}  // namespace rack::gui
