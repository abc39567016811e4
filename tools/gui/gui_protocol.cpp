#include "gui_protocol.h"

#include <cmath>
#include <cstring>
#include <set>

namespace rack::gui {

namespace {

using nlohmann::json;

struct OpSpec {
  const char* name;
  Op op;
  std::set<std::string> keys;  // required keys besides "op" (and the optional "id")
};

const std::vector<OpSpec>& specs() {
  static const std::vector<OpSpec> kSpecs = {
      {"switch", Op::kSwitch, {"component", "on"}},
      {"all_off", Op::kAllOff, {"system"}},
      {"get_params", Op::kGetParams, {"component"}},
      {"set_param", Op::kSetParam, {"component", "name", "value"}},
      {"set_destination", Op::kSetDestination, {"system", "x", "y"}},
      {"set_pose", Op::kSetPose, {"system", "x", "y", "phi"}},
      {"joystick", Op::kJoystick, {"system", "vx", "omega"}},
      {"joystick_release", Op::kJoystickRelease, {"system"}},
      {"follow_path", Op::kFollowPath, {"system"}},
  };
  return kSpecs;
}

// JSON's own type names, for messages.
std::string type_of(const json& v) {
  if (v.is_number_integer()) return "integer";
  if (v.is_number_float()) return "number";
  return v.type_name();
}

struct Bad {
  std::string message;
};

double number(const json& msg, const char* key, double limit) {
  const json& v = msg.at(key);
  if (!v.is_number()) throw Bad{std::string("key '") + key + "': expected a number, got " + type_of(v)};
  const double d = v.get<double>();
  if (!std::isfinite(d) || std::fabs(d) > limit) {
    throw Bad{std::string("key '") + key + "': " + v.dump() + " is outside -" + json(limit).dump() + ".." +
              json(limit).dump()};
  }
  return d;
}

uint8_t system_of(const json& msg) {
  const json& v = msg.at("system");
  if (!v.is_number_integer()) throw Bad{"key 'system': expected an integer 0..254, got " + type_of(v)};
  const auto s = v.get<int64_t>();
  if (s < 0 || s > 254) throw Bad{"key 'system': " + v.dump() + " is not a robot's system number 0..254"};
  return static_cast<uint8_t>(s);
}

tims::Address component_of(const json& msg) {
  const json& v = msg.at("component");
  if (!v.is_string()) throw Bad{"key 'component': expected an address text such as Chassis(0/0), got " + type_of(v)};
  const auto text = v.get<std::string>();
  const auto a = tims::parse_address(text);
  if (!a) throw Bad{"key 'component': '" + text + "' is not an address such as Chassis(0/0)"};
  if (a->mailbox() != 0) throw Bad{"key 'component': '" + text + "' names a mailbox, not a component"};
  return *a;
}

}  // namespace

const char* op_name(Op op) noexcept {
  for (const auto& s : specs()) {
    if (s.op == op) return s.name;
  }
  return "?";
}

std::variant<Request, ParseError> parse_request(const std::string& text) {
  json msg = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (msg.is_discarded()) return ParseError{std::nullopt, "not JSON (" + std::to_string(text.size()) + " bytes)"};
  if (!msg.is_object()) return ParseError{std::nullopt, "expected a JSON object, got " + type_of(msg)};
  Request r;
  if (const auto it = msg.find("id"); it != msg.end()) {
    if (!it->is_number_integer()) return ParseError{std::nullopt, "key 'id': expected an integer, got " + type_of(*it)};
    r.id = it->get<int64_t>();
  }
  const auto op_it = msg.find("op");
  if (op_it == msg.end()) return ParseError{r.id, "missing key 'op'"};
  if (!op_it->is_string()) return ParseError{r.id, "key 'op': expected a string, got " + type_of(*op_it)};
  const auto op_text = op_it->get<std::string>();
  const OpSpec* spec = nullptr;
  for (const auto& s : specs()) {
    if (op_text == s.name) spec = &s;
  }
  if (spec == nullptr) return ParseError{r.id, "unknown op '" + op_text + "'"};
  r.op = spec->op;
  for (const auto& [key, value] : msg.items()) {
    if (key != "op" && key != "id" && spec->keys.count(key) == 0) {
      return ParseError{r.id, op_text + ": unknown key '" + key + "'"};
    }
  }
  for (const auto& key : spec->keys) {
    if (!msg.contains(key)) return ParseError{r.id, op_text + ": missing key '" + key + "'"};
  }
  try {
    switch (r.op) {
      case Op::kSwitch: {
        r.component = component_of(msg);
        const json& on = msg.at("on");
        if (!on.is_boolean()) throw Bad{"key 'on': expected true or false, got " + type_of(on)};
        r.on = on.get<bool>();
        break;
      }
      case Op::kGetParams: r.component = component_of(msg); break;
      case Op::kSetParam: {
        r.component = component_of(msg);
        const json& n = msg.at("name");
        if (!n.is_string()) throw Bad{"key 'name': expected a string, got " + type_of(n)};
        r.param_name = n.get<std::string>();
        if (r.param_name.empty() || r.param_name.size() >= wire::kParamNameLen) {
          throw Bad{"key 'name': a parameter name has 1.." + std::to_string(wire::kParamNameLen - 1) + " characters"};
        }
        r.param_value = msg.at("value");
        if (!r.param_value.is_primitive() || r.param_value.is_null()) {
          throw Bad{"key 'value': expected a number, boolean or string, got " + type_of(r.param_value)};
        }
        break;
      }
      case Op::kAllOff:
      case Op::kJoystickRelease:
      case Op::kFollowPath: r.system = system_of(msg); break;
      case Op::kSetDestination:
        r.system = system_of(msg);
        r.x = number(msg, "x", kMaxCoordinate);
        r.y = number(msg, "y", kMaxCoordinate);
        break;
      case Op::kSetPose:
        r.system = system_of(msg);
        r.x = number(msg, "x", kMaxCoordinate);
        r.y = number(msg, "y", kMaxCoordinate);
        r.phi = number(msg, "phi", 4.0 * M_PI);
        break;
      case Op::kJoystick:
        r.system = system_of(msg);
        r.vx = number(msg, "vx", kMaxJoystickSpeed);
        r.omega = number(msg, "omega", kMaxJoystickOmega);
        break;
    }
  } catch (const Bad& b) {
    return ParseError{r.id, op_text + ": " + b.message};
  }
  return r;
}

std::string check_param_value(const json& value, wire::ParamRecord& record) {
  const auto kind = static_cast<wire::ParamKind>(record.kind);
  switch (kind) {
    case wire::ParamKind::kInt:
      if (!value.is_number_integer()) return "expected an integer, got " + type_of(value);
      record.int_value = value.get<int64_t>();
      return "";
    case wire::ParamKind::kFloat: {
      if (!value.is_number()) return "expected a number, got " + type_of(value);
      const double d = value.get<double>();
      if (!std::isfinite(d)) return "expected a finite number";
      record.float_value = d;
      return "";
    }
    case wire::ParamKind::kBool:
      if (!value.is_boolean()) return "expected true or false, got " + type_of(value);
      record.int_value = value.get<bool>() ? 1 : 0;
      return "";
    case wire::ParamKind::kString: {
      if (!value.is_string()) return "expected a string, got " + type_of(value);
      const auto s = value.get<std::string>();
      if (s.size() >= wire::kParamStringLen) {
        return "a string of at most " + std::to_string(wire::kParamStringLen - 1) + " characters";
      }
      if (s.find('\0') != std::string::npos) return "a string without NUL characters";
      std::memset(record.string_value, 0, sizeof record.string_value);
      std::memcpy(record.string_value, s.data(), s.size());
      return "";
    }
  }
  return "the parameter has an unknown kind " + std::to_string(record.kind);
}

std::variant<nlohmann::json, std::string> latency_json(const wire::LatencyHistogram& h) {
  if (const char* bad = wire::check_latency_histogram(h)) return std::string(bad);
  nlohmann::json lower = nlohmann::json::array(), counts = nlohmann::json::array();
  for (std::size_t j = 0; j < h.bucket_count; ++j) {
    lower.push_back(h.lower_ns[j]);
    counts.push_back(h.counts[j]);
  }
  return nlohmann::json{{"data_task", h.data_task},
                        {"period_ns", h.period_ns},
                        {"cycles", h.cycles},
                        {"overruns", h.overruns},
                        {"samples", h.samples},
                        {"latency_ns",
                         {{"min", h.min_ns},
                          {"p50", h.p50_ns},
                          {"p99", h.p99_ns},
                          {"p999", h.p999_ns},
                          {"max", h.max_ns},
                          {"mean", h.mean_ns}}},
                        {"lower_ns", std::move(lower)},
                        {"counts", std::move(counts)}};
}

std::string error_message(const ParseError& e) {
  json j = {{"type", "error"}, {"error", e.message}};
  if (e.id) j["id"] = *e.id;
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string result_message(const std::optional<int64_t>& id, Op op, bool ok, const std::string& text) {
  json j = {{"type", "result"}, {"op", op_name(op)}, {"ok", ok}, {"text", text}};
  if (id) j["id"] = *id;
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace rack::gui
