#include "gui_protocol.h"

#include "rack/client/session.h"  // parse_named_address
#include "rack/core/payload_json.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

namespace rack::gui {

namespace {

using nlohmann::json;

struct OpSpec {
  const char* name;
  Op op;
  std::set<std::string> keys;      // required keys besides "op" (and the optional "id")
  std::set<std::string> optional;  // keys that may be left out
};

const std::vector<OpSpec>& specs() {
  static const std::vector<OpSpec> kSpecs = {
      {"switch", Op::kSwitch, {"component", "on"}, {}},
      {"all_off", Op::kAllOff, {"system"}, {}},
      {"get_params", Op::kGetParams, {"component"}, {}},
      {"set_param", Op::kSetParam, {"component", "name", "value"}, {}},
      {"set_destination", Op::kSetDestination, {"system", "x", "y"}, {}},
      {"set_pose", Op::kSetPose, {"system", "x", "y", "phi"}, {}},
      {"joystick", Op::kJoystick, {"system", "vx", "omega"}, {}},
      {"joystick_release", Op::kJoystickRelease, {"system"}, {}},
      {"follow_path", Op::kFollowPath, {"system"}, {}},
      {"get_class", Op::kGetClass, {"component"}, {}},
      {"command", Op::kCommand, {"component", "name", "fields"}, {}},
      {"trace", Op::kTrace, {"system", "host", "duration_s"}, {}},
      {"command_json", Op::kCommandJson, {"component", "command", "body"}, {}},
      {"subscribe", Op::kSubscribe, {"component"}, {"period_ms"}},
      {"unsubscribe", Op::kUnsubscribe, {"component"}, {}},
  };
  return kSpecs;
}

// JSON's own type names, for messages.
std::string type_of(const json& v) {
  if (v.is_number_integer()) return "integer";
  if (v.is_number_float()) return "number";
  return v.type_name();
}

// A refusal on the way (thrown inside parse_request only, caught there).
struct Bad {
  std::string message;
  Refusal reason = Refusal::kBadValue;
};

// A client's text for a message: at most kMaxQuoted bytes (cut at a character
// boundary), control characters as '?'.
std::string quote(std::string_view t) {
  std::size_t n = std::min(t.size(), kMaxQuoted);
  while (n > 0 && n < t.size() && (static_cast<unsigned char>(t[n]) & 0xC0u) == 0x80u) --n;
  std::string out;
  out.reserve(n + 3);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(t[i]);
    out += c < 0x20 || c == 0x7F ? '?' : t[i];
  }
  if (n < t.size()) out += "...";
  return out;
}

// An integer that fits int64_t (JSON integers above it arrive as unsigned: refused,
// never wrapped).
std::optional<int64_t> as_int64(const json& v) {
  if (v.is_number_unsigned()) {
    const auto u = v.get<uint64_t>();
    if (u > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) return std::nullopt;
    return static_cast<int64_t>(u);
  }
  if (v.is_number_integer()) return v.get<int64_t>();
  return std::nullopt;
}

double number(const json& msg, const char* key, double limit) {
  const json& v = msg.at(key);
  if (!v.is_number()) throw Bad{std::string("key '") + key + "': expected a number, got " + type_of(v)};
  const double d = v.get<double>();
  if (!std::isfinite(d) || std::fabs(d) > limit) {
    throw Bad{std::string("key '") + key + "': " + quote(v.dump()) + " is outside -" + json(limit).dump() + ".." +
              json(limit).dump()};
  }
  return d;
}

uint8_t system_of(const json& msg) {
  const json& v = msg.at("system");
  if (!v.is_number_integer()) throw Bad{"key 'system': expected an integer 0..254, got " + type_of(v)};
  const auto s = as_int64(v);
  if (!s || *s < 0 || *s > 254)
    throw Bad{"key 'system': " + quote(v.dump()) + " is not a robot's system number 0..254"};
  return static_cast<uint8_t>(*s);
}

// The address, and the class name when TiMS does not know it (every component class:
// the backend resolves it against the classes' descriptions).
std::pair<tims::Address, std::string> component_of(const json& msg) {
  const json& v = msg.at("component");
  if (!v.is_string()) throw Bad{"key 'component': expected an address text such as Chassis(0/0), got " + type_of(v)};
  const auto& text = v.get_ref<const std::string&>();
  std::optional<tims::Address> a;
  std::string cls;
  if (text.size() <= kMaxQuoted) {
    a = tims::parse_address(text);
    if (!a) {
      if (auto named = client::parse_named_address(text)) {
        cls = std::move(named->first);
        a = named->second;
      }
    }
  }
  if (!a) throw Bad{"key 'component': '" + quote(text) + "' is not an address such as Chassis(0/0)"};
  if (a->mailbox() != 0) throw Bad{"key 'component': '" + quote(text) + "' names a mailbox, not a component"};
  return {*a, cls};
}

// JSON text -> value, refusing what the protocol never needs: deep nesting (bounded
// before it is built) and a key given twice (nlohmann would keep the last one
// silently). Throws Bad.
json parse_json(std::string_view text) {
  std::vector<std::set<std::string>> keys;  // per open object
  const json::parser_callback_t check = [&keys](int depth, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        if (depth >= kMaxRequestDepth) {
          throw Bad{"nested deeper than " + std::to_string(kMaxRequestDepth) + " levels", Refusal::kTooDeep};
        }
        if (event == json::parse_event_t::object_start) keys.emplace_back();
        break;
      case json::parse_event_t::key:
        if (!keys.empty() && parsed.is_string() && !keys.back().insert(parsed.get<std::string>()).second) {
          throw Bad{"key '" + quote(parsed.get_ref<const std::string&>()) + "' given twice", Refusal::kDuplicateKey};
        }
        break;
      case json::parse_event_t::object_end:
        if (!keys.empty()) keys.pop_back();
        break;
      default: break;
    }
    return true;
  };
  try {
    return json::parse(text.begin(), text.end(), check, /*allow_exceptions=*/true);
  } catch (const json::parse_error& e) {
    // e.what(): "[json.exception.parse_error.101] parse error at line 1, column 5: ..."
    std::string why = e.what();
    if (const auto at = why.find("] "); at != std::string::npos) why.erase(0, at + 2);
    throw Bad{"not JSON (" + std::to_string(text.size()) + " bytes): at byte " + std::to_string(e.byte) + ": " +
                  quote(why.substr(0, 4 * kMaxQuoted)),
              Refusal::kNotJson};
  } catch (const json::exception& e) {  // a number JSON can hold but a double cannot (1e400)
    std::string why = e.what();
    if (const auto at = why.find("] "); at != std::string::npos) why.erase(0, at + 2);
    throw Bad{"not JSON (" + std::to_string(text.size()) + " bytes): " + quote(why), Refusal::kNotJson};
  }
}

std::variant<Request, ParseError> parse_checked(std::string_view text) {
  if (text.size() > kMaxRequestBytes) {
    return ParseError{std::nullopt,
                      "message of " + std::to_string(text.size()) + " bytes, at most " +
                          std::to_string(kMaxRequestBytes),
                      Refusal::kTooLarge};
  }
  json msg;
  try {
    msg = parse_json(text);
  } catch (const Bad& b) {
    return ParseError{std::nullopt, b.message, b.reason};
  }
  if (!msg.is_object())
    return ParseError{std::nullopt, "expected a JSON object, got " + type_of(msg), Refusal::kNotObject};
  Request r;
  if (const auto it = msg.find("id"); it != msg.end()) {
    if (!it->is_number_integer()) {
      return ParseError{std::nullopt, "key 'id': expected an integer, got " + type_of(*it), Refusal::kBadValue};
    }
    const auto id = as_int64(*it);
    if (!id) return ParseError{std::nullopt, "key 'id': " + quote(it->dump()) + " is above 2^63-1", Refusal::kBadValue};
    r.id = *id;
  }
  const auto op_it = msg.find("op");
  if (op_it == msg.end()) return ParseError{r.id, "missing key 'op'", Refusal::kBadOp};
  if (!op_it->is_string())
    return ParseError{r.id, "key 'op': expected a string, got " + type_of(*op_it), Refusal::kBadOp};
  const auto& op_text = op_it->get_ref<const std::string&>();
  const OpSpec* spec = nullptr;
  for (const auto& s : specs()) {
    if (op_text == s.name) spec = &s;
  }
  if (spec == nullptr) return ParseError{r.id, "unknown op '" + quote(op_text) + "'", Refusal::kBadOp};
  r.op = spec->op;
  for (const auto& [key, value] : msg.items()) {
    if (key != "op" && key != "id" && spec->keys.count(key) == 0 && spec->optional.count(key) == 0) {
      return ParseError{r.id, std::string(spec->name) + ": unknown key '" + quote(key) + "'", Refusal::kBadKey};
    }
  }
  for (const auto& key : spec->keys) {
    if (!msg.contains(key)) {
      return ParseError{r.id, std::string(spec->name) + ": missing key '" + key + "'", Refusal::kBadKey};
    }
  }
  try {
    switch (r.op) {
      case Op::kSwitch: {
        std::tie(r.component, r.component_class) = component_of(msg);
        const json& on = msg.at("on");
        if (!on.is_boolean()) throw Bad{"key 'on': expected true or false, got " + type_of(on)};
        r.on = on.get<bool>();
        break;
      }
      case Op::kGetParams:
      case Op::kGetClass:
      case Op::kUnsubscribe: std::tie(r.component, r.component_class) = component_of(msg); break;
      case Op::kSubscribe:
        std::tie(r.component, r.component_class) = component_of(msg);
        if (msg.contains("period_ms")) {
          r.period_ms = number(msg, "period_ms", kMaxStreamPeriodMs);
          if (r.period_ms < 0.0) throw Bad{"key 'period_ms': 0 (every sample) or a period in ms"};
        }
        break;
      case Op::kCommand: {
        std::tie(r.component, r.component_class) = component_of(msg);
        const json& n = msg.at("name");
        if (!n.is_string()) throw Bad{"key 'name': expected a command name, got " + type_of(n)};
        r.command_name = n.get<std::string>();
        if (r.command_name.empty() || r.command_name.size() > kMaxFieldName) {
          throw Bad{"key 'name': a command name has 1.." + std::to_string(kMaxFieldName) + " bytes"};
        }
        const json& f = msg.at("fields");
        if (!f.is_object()) throw Bad{"key 'fields': expected an object of field: value, got " + type_of(f)};
        if (f.size() > kMaxCommandFields) {
          throw Bad{"key 'fields': " + std::to_string(f.size()) + " fields, at most " +
                    std::to_string(kMaxCommandFields)};
        }
        for (const auto& [key, value] : f.items()) {
          if (key.empty() || key.size() > kMaxFieldName) {
            throw Bad{"key 'fields': a field name has 1.." + std::to_string(kMaxFieldName) + " bytes"};
          }
          std::string value_text;
          if (value.is_string()) {
            value_text = value.get<std::string>();
          } else if (value.is_boolean()) {
            value_text = value.get<bool>() ? "true" : "false";
          } else if (value.is_number_integer()) {
            const auto v = as_int64(value);
            if (!v) throw Bad{"field '" + quote(key) + "': " + quote(value.dump()) + " is above 2^63-1"};
            value_text = std::to_string(*v);
          } else if (value.is_number_float()) {
            value_text = value.dump();
          } else {
            throw Bad{"field '" + quote(key) + "': expected a text, number or boolean, got " + type_of(value)};
          }
          if (value_text.size() > kMaxFieldText) {
            throw Bad{"field '" + quote(key) + "': a value of at most " + std::to_string(kMaxFieldText) + " bytes"};
          }
          r.fields.emplace_back(key, std::move(value_text));
        }
        break;
      }
      case Op::kSetParam: {
        std::tie(r.component, r.component_class) = component_of(msg);
        const json& n = msg.at("name");
        if (!n.is_string()) throw Bad{"key 'name': expected a string, got " + type_of(n)};
        r.param_name = n.get<std::string>();
        if (r.param_name.empty() || r.param_name.size() >= wire::kParamNameLen ||
            r.param_name.find('\0') != std::string::npos) {
          throw Bad{"key 'name': a parameter name has 1.." + std::to_string(wire::kParamNameLen - 1) +
                    " characters and no NUL"};
        }
        r.param_value = msg.at("value");
        if (!r.param_value.is_primitive() || r.param_value.is_null()) {
          throw Bad{"key 'value': expected a number, boolean or string, got " + type_of(r.param_value)};
        }
        if (r.param_value.is_number_integer() && !as_int64(r.param_value)) {
          throw Bad{"key 'value': " + quote(r.param_value.dump()) + " is above 2^63-1"};
        }
        if (r.param_value.is_string() && r.param_value.get_ref<const std::string&>().size() >= wire::kParamStringLen) {
          throw Bad{"key 'value': a string of at most " + std::to_string(wire::kParamStringLen - 1) + " bytes"};
        }
        break;
      }
      case Op::kAllOff:
      case Op::kJoystickRelease:
      case Op::kFollowPath: r.system = system_of(msg); break;
      case Op::kTrace: {
        r.system = system_of(msg);
        const json& h = msg.at("host");
        if (!h.is_string()) throw Bad{"key 'host': expected a host name (or \"\"), got " + type_of(h)};
        r.host = h.get<std::string>();
        if (r.host.size() > kMaxFieldName) throw Bad{"key 'host': at most " + std::to_string(kMaxFieldName) + " bytes"};
        r.duration_s = number(msg, "duration_s", kMaxTraceSeconds);
        if (!(r.duration_s > 0.0)) throw Bad{"key 'duration_s': a duration above 0 s"};
        break;
      }
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
      case Op::kCommandJson: {
        std::tie(r.component, r.component_class) = component_of(msg);
        const json& c = msg.at("command");
        if (!c.is_string()) throw Bad{"key 'command': expected a command name such as INIT, got " + type_of(c)};
        const auto& name = c.get_ref<const std::string&>();
        const bool name_ok = !name.empty() && name.size() <= kMaxCommandName &&
                             std::all_of(name.begin(), name.end(), [](char ch) {
                               return (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_';
                             });
        if (!name_ok) {
          throw Bad{"key 'command': '" + quote(name) + "' is not a command name (1.." +
                    std::to_string(kMaxCommandName) + " of A-Z, 0-9, _)"};
        }
        r.command = name;
        r.body = msg.at("body");
        if (!r.body.is_object()) throw Bad{"key 'body': expected an object of field values, got " + type_of(r.body)};
        break;
      }
    }
  } catch (const Bad& b) {
    return ParseError{r.id, std::string(spec->name) + ": " + b.message, b.reason};
  }
  return r;
}

}  // namespace

const char* op_name(Op op) noexcept {
  for (const auto& s : specs()) {
    if (s.op == op) return s.name;
  }
  return "?";
}

const char* describe(Refusal r) noexcept {
  switch (r) {
    case Refusal::kTooLarge: return "too_large";
    case Refusal::kNotJson: return "not_json";
    case Refusal::kTooDeep: return "too_deep";
    case Refusal::kDuplicateKey: return "duplicate_key";
    case Refusal::kNotObject: return "not_object";
    case Refusal::kBadOp: return "bad_op";
    case Refusal::kBadKey: return "bad_key";
    case Refusal::kBadValue: return "bad_value";
    case Refusal::kBusy: return "busy";
    case Refusal::kBinary: return "binary";
  }
  return "?";
}

std::variant<Request, ParseError> parse_request(std::string_view text) noexcept {
  try {
    return parse_checked(text);
  } catch (const std::bad_alloc&) {
    return ParseError{std::nullopt, "message of " + std::to_string(text.size()) + " bytes: out of memory",
                      Refusal::kTooLarge};
  } catch (const std::exception& e) {  // a defect here, not the client's: still refused, never fatal
    return ParseError{std::nullopt, std::string("message could not be decoded: ") + e.what(), Refusal::kNotJson};
  }
}

namespace {

// One JSON value as set_field_from_text's text: numbers as JSON writes them, booleans
// as true/false, strings as they are, arrays of numbers or booleans comma-separated.
std::optional<std::string> field_text(const json& v) {
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  if (v.is_number()) return v.dump();
  if (v.is_string()) return v.get<std::string>();
  if (v.is_array()) {
    std::string text;
    for (const auto& e : v) {
      if (!e.is_number() && !e.is_boolean()) return std::nullopt;
      if (!text.empty()) text += ',';
      text += e.is_boolean() ? (e.get<bool>() ? "true" : "false") : e.dump();
    }
    return text;
  }
  return std::nullopt;
}

}  // namespace

std::string encode_command_body(const json& body, const rack::TypeDescription* type,
                                std::vector<std::byte>& out) noexcept {
  try {
    if (!body.is_object()) return "body: expected an object, got " + type_of(body);
    if (type == nullptr) {
      out.clear();
      return body.empty() ? "" : "the command takes no body (got " + std::to_string(body.size()) + " fields)";
    }
    const auto fields = type->field_table();
    out.assign(type->size, std::byte{0});
    for (const auto& item : body.items()) {
      // (not a structured binding: clang 14, the fuzzing compiler, cannot capture one)
      const std::string& key = item.key();
      const json& value = item.value();
      const auto f = std::find_if(fields.begin(), fields.end(),
                                  [&key](const tims::FieldDesc& d) { return key == d.name; });
      if (f == fields.end()) return "field '" + quote(key) + "': " + type->name + " has no such field";
      const auto text = field_text(value);
      if (!text)
        return "field '" + quote(key) + "': expected a number, boolean, string or array of numbers, got " +
               type_of(value);
      if (value.is_array() && value.size() > f->count) {
        return "field '" + quote(key) + "': " + std::to_string(value.size()) + " elements, at most " +
               std::to_string(f->count);
      }
      const std::string why = rack::set_field_from_text(*f, out, *text);
      if (!why.empty()) return "field '" + quote(key) + "': " + quote(why);
    }
    return "";
  } catch (const std::exception& e) {  // out of memory: refused, never fatal
    return std::string("body: ") + e.what();
  }
}

std::string check_param_value(const json& value, wire::ParamRecord& record) {
  const auto kind = static_cast<wire::ParamKind>(record.kind);
  switch (kind) {
    case wire::ParamKind::kInt:
      if (!value.is_number_integer()) return "expected an integer, got " + type_of(value);
      if (const auto v = as_int64(value)) {
        record.int_value = *v;
        return "";
      }
      return quote(value.dump()) + " is above 2^63-1";
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
  json j = {{"type", "error"}, {"error", e.message}, {"reason", describe(e.reason)}};
  if (e.id) j["id"] = *e.id;
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string result_message(const std::optional<int64_t>& id, Op op, bool ok, const std::string& text) {
  json j = {{"type", "result"}, {"op", op_name(op)}, {"ok", ok}, {"text", text}};
  if (id) j["id"] = *id;
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace rack::gui
