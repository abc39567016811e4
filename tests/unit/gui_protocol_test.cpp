// rack-gui's WebSocket protocol: every accepted message and the ways a message is
// refused (nothing reaches a robot then), and the parameter type checks.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <variant>

#include "gui_protocol.h"

namespace rack::gui {
namespace {

Request ok(const std::string& text) {
  auto r = parse_request(text);
  if (auto* e = std::get_if<ParseError>(&r)) {
    ADD_FAILURE() << text << " refused: " << e->message;
    return {};
  }
  return std::get<Request>(r);
}

std::string refused(const std::string& text) {
  auto r = parse_request(text);
  if (!std::holds_alternative<ParseError>(r)) {
    ADD_FAILURE() << text << " was accepted";
    return "";
  }
  return std::get<ParseError>(r).message;
}

TEST(GuiProtocolTest, AcceptsEveryOp) {
  auto r = ok(R"j({"op":"switch","component":"Chassis(0/0)","on":true,"id":7})j");
  EXPECT_EQ(r.op, Op::kSwitch);
  // A component class by name (rack-gui links no class): system and instance here,
  // the class resolved by the backend against the classes' descriptions.
  EXPECT_EQ(r.component, tims::Address::make(0, 0, 0));
  EXPECT_EQ(r.component_class, "Chassis");
  EXPECT_TRUE(r.on);
  ASSERT_TRUE(r.id.has_value());
  EXPECT_EQ(*r.id, 7);

  r = ok(R"j({"op":"all_off","system":3})j");
  EXPECT_EQ(r.op, Op::kAllOff);
  EXPECT_EQ(r.system, 3);
  EXPECT_FALSE(r.id.has_value());

  r = ok(R"j({"op":"get_params","component":"Pilot(1/2)"})j");
  EXPECT_EQ(r.component, tims::Address::make(1, 0, 2));
  EXPECT_EQ(r.component_class, "Pilot");
  // A class TiMS names, or a class id: the whole address, no name to resolve.
  r = ok(R"j({"op":"get_params","component":"Class0x91(2/0)"})j");
  EXPECT_EQ(r.component, tims::Address::make(2, 0x91, 0));
  EXPECT_EQ(r.component_class, "");
  r = ok(R"j({"op":"get_params","component":"Executor(1/0)"})j");
  EXPECT_EQ(r.component, tims::Address::make(1, tims::classes::kExecutor, 0));
  EXPECT_EQ(r.component_class, "");
  EXPECT_NE(refused(R"j({"op":"get_params","component":"Counter(2/0)#1"})j").find("names a mailbox"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"get_params","component":"Coun-ter(2/0)"})j").find("is not an address"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"get_params","component":"Counter(2/256)"})j").find("is not an address"),
            std::string::npos);

  r = ok(R"j({"op":"set_param","component":"Pilot(0/0)","name":"vx_max","value":0.5})j");
  EXPECT_EQ(r.param_name, "vx_max");
  EXPECT_DOUBLE_EQ(r.param_value.get<double>(), 0.5);

  r = ok(R"j({"op":"set_destination","system":0,"x":10,"y":-8.5})j");
  EXPECT_DOUBLE_EQ(r.x, 10.0);
  EXPECT_DOUBLE_EQ(r.y, -8.5);

  r = ok(R"j({"op":"set_pose","system":0,"x":4,"y":7.2,"phi":-1.5})j");
  EXPECT_DOUBLE_EQ(r.phi, -1.5);

  r = ok(R"j({"op":"joystick","system":0,"vx":0.3,"omega":-0.2})j");
  EXPECT_EQ(r.op, Op::kJoystick);
  EXPECT_DOUBLE_EQ(r.vx, 0.3);
  EXPECT_DOUBLE_EQ(r.omega, -0.2);

  EXPECT_EQ(ok(R"j({"op":"joystick_release","system":0})j").op, Op::kJoystickRelease);
  EXPECT_EQ(ok(R"j({"op":"follow_path","system":0})j").op, Op::kFollowPath);
}

TEST(GuiProtocolTest, ClassCommandsByNameWithTheirFieldsAsText) {
  auto r = ok(R"j({"op":"get_class","component":"Pilot(0/0)"})j");
  EXPECT_EQ(r.op, Op::kGetClass);
  EXPECT_EQ(r.component, tims::Address::make(0, 0, 0));
  EXPECT_EQ(r.component_class, "Pilot");
  r = ok(
      R"j({"op":"command","component":"Pilot(0/0)","name":"SET_DESTINATION","fields":{"x":"2.5","y":-1,"z":0.25,"b":true}})j");
  EXPECT_EQ(r.op, Op::kCommand);
  EXPECT_EQ(r.command_name, "SET_DESTINATION");
  ASSERT_EQ(r.fields.size(), 4u);
  // nlohmann keeps the object's keys sorted.
  EXPECT_EQ(r.fields[0], (std::pair<std::string, std::string>("b", "true")));
  EXPECT_EQ(r.fields[1], (std::pair<std::string, std::string>("x", "2.5")));
  EXPECT_EQ(r.fields[2], (std::pair<std::string, std::string>("y", "-1")));
  EXPECT_EQ(r.fields[3], (std::pair<std::string, std::string>("z", "0.25")));
  EXPECT_TRUE(ok(R"j({"op":"command","component":"Pilot(0/0)","name":"FOLLOW_PATH","fields":{}})j").fields.empty());

  EXPECT_NE(refused(R"j({"op":"command","component":"Pilot(0/0)","name":"X"})j").find("missing key 'fields'"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command","component":"Pilot(0/0)","name":"","fields":{}})j").find("key 'name'"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command","component":"Pilot(0/0)","name":"X","fields":[1]})j")
                .find("key 'fields': expected an object"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command","component":"Pilot(0/0)","name":"X","fields":{"x":[1]}})j")
                .find("field 'x': expected a text, number or boolean, got array"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command","component":"Pilot(0/0)","name":"X","fields":{"x":null}})j").find("got null"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command","component":"Pilot(0/0)","name":"X","fields":{"x":18446744073709551615}})j")
                .find("above 2^63-1"),
            std::string::npos);
  std::string many = R"j({"op":"command","component":"Pilot(0/0)","name":"X","fields":{)j";
  for (std::size_t i = 0; i <= kMaxCommandFields; ++i) many += (i ? ",\"f" : "\"f") + std::to_string(i) + "\":1";
  EXPECT_NE(refused(many + "}}").find("at most 64"), std::string::npos);
  EXPECT_NE(
      refused(R"j({"op":"command","component":"Pilot(0/0)","name":"X","fields":{"":1}})j").find("a field name has"),
      std::string::npos);
}

TEST(GuiProtocolTest, ALiveTraceNamesARobotAHostAndADuration) {
  auto r = ok(R"j({"op":"trace","system":0,"host":"","duration_s":0.5})j");
  EXPECT_EQ(r.op, Op::kTrace);
  EXPECT_EQ(r.host, "");
  EXPECT_DOUBLE_EQ(r.duration_s, 0.5);
  EXPECT_EQ(ok(R"j({"op":"trace","system":1,"host":"sim-mcl","duration_s":10})j").host, "sim-mcl");
  EXPECT_NE(refused(R"j({"op":"trace","system":0,"host":"","duration_s":0})j").find("above 0 s"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"trace","system":0,"host":"","duration_s":-1})j").find("above 0 s"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"trace","system":0,"host":"","duration_s":11})j").find("key 'duration_s'"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"trace","system":0,"host":3,"duration_s":1})j").find("key 'host'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"trace","system":0,"duration_s":1})j").find("missing key 'host'"), std::string::npos);
}

TEST(GuiProtocolTest, RefusesMalformedMessagesSayingWhat) {
  EXPECT_NE(refused("{\"op\":").find("not JSON"), std::string::npos);
  EXPECT_NE(refused("").find("not JSON"), std::string::npos);
  EXPECT_NE(refused("[1,2]").find("expected a JSON object, got array"), std::string::npos);
  EXPECT_NE(refused("42").find("expected a JSON object"), std::string::npos);
  EXPECT_NE(refused("{}").find("missing key 'op'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":5})j").find("key 'op': expected a string, got integer"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"explode"})j").find("unknown op 'explode'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"all_off"})j").find("all_off: missing key 'system'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"all_off","system":0,"force":true})j").find("unknown key 'force'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"all_off","system":0,"id":"x"})j").find("key 'id': expected an integer"),
            std::string::npos);
}

TEST(GuiProtocolTest, RefusesWrongTypesAndRanges) {
  EXPECT_NE(refused(R"j({"op":"switch","component":"Chassis(0/0)","on":"yes"})j")
                .find("key 'on': expected true or false, got string"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":"Chassis(0/0)","on":1})j").find("got integer"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":17,"on":true})j").find("key 'component'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":"chassis","on":true})j").find("'chassis' is not an address"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":"Chassis(0/0)#3","on":true})j").find("names a mailbox"),
            std::string::npos);
  EXPECT_NE(
      refused(R"j({"op":"set_destination","system":0,"x":"10","y":8})j").find("key 'x': expected a number, got string"),
      std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_destination","system":0,"x":1e300,"y":8})j").find("key 'x'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_destination","system":0.5,"x":1,"y":8})j").find("key 'system'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_destination","system":255,"x":1,"y":8})j").find("0..254"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_destination","system":-1,"x":1,"y":8})j").find("0..254"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"joystick","system":0,"vx":50,"omega":0})j").find("key 'vx'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"joystick","system":0,"vx":null,"omega":0})j").find("got null"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_param","component":"Pilot(0/0)","name":"","value":1})j").find("key 'name'"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_param","component":"Pilot(0/0)","name":"a","value":[1]})j").find("key 'value'"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_param","component":"Pilot(0/0)","name":"a","value":null})j").find("key 'value'"),
            std::string::npos);
}

TEST(GuiProtocolTest, ErrorMessagesAreJsonAndKeepTheId) {
  auto r = parse_request(R"j({"op":"all_off","id":12})j");
  ASSERT_TRUE(std::holds_alternative<ParseError>(r));
  const auto j = nlohmann::json::parse(error_message(std::get<ParseError>(r)));
  EXPECT_EQ(j["type"], "error");
  EXPECT_EQ(j["id"], 12);
  EXPECT_NE(j["error"].get<std::string>().find("missing key 'system'"), std::string::npos);
  // Invalid UTF-8 in what the client sent never breaks the reply.
  const auto bad = parse_request("{\"op\":\"\xff\xfe\"}");
  ASSERT_TRUE(std::holds_alternative<ParseError>(bad));
  EXPECT_TRUE(nlohmann::json::accept(error_message(std::get<ParseError>(bad))));
}

wire::ParamRecord record(wire::ParamKind kind) {
  wire::ParamRecord p;
  p.kind = static_cast<uint8_t>(kind);
  return p;
}

TEST(GuiProtocolTest, ParamValuesMustHaveTheParametersKind) {
  using nlohmann::json;
  auto p = record(wire::ParamKind::kInt);
  EXPECT_EQ(check_param_value(json(42), p), "");
  EXPECT_EQ(p.int_value, 42);
  EXPECT_NE(check_param_value(json(4.5), p), "");
  EXPECT_NE(check_param_value(json("42"), p), "");
  EXPECT_NE(check_param_value(json(true), p), "");
  EXPECT_EQ(p.int_value, 42) << "a refused value leaves the record as it was";

  p = record(wire::ParamKind::kFloat);
  EXPECT_EQ(check_param_value(json(2), p), "");
  EXPECT_DOUBLE_EQ(p.float_value, 2.0);
  EXPECT_EQ(check_param_value(json(0.25), p), "");
  EXPECT_DOUBLE_EQ(p.float_value, 0.25);
  EXPECT_NE(check_param_value(json("0.5"), p), "");

  p = record(wire::ParamKind::kBool);
  EXPECT_EQ(check_param_value(json(true), p), "");
  EXPECT_EQ(p.int_value, 1);
  EXPECT_NE(check_param_value(json(1), p), "");
  EXPECT_NE(check_param_value(json("true"), p), "");

  p = record(wire::ParamKind::kString);
  EXPECT_EQ(check_param_value(json("10,8"), p), "");
  EXPECT_STREQ(p.string_value, "10,8");
  EXPECT_NE(check_param_value(json(std::string(wire::kParamStringLen, 'x')), p), "");
  EXPECT_NE(check_param_value(json(std::string("a\0b", 3)), p), "");
  EXPECT_NE(check_param_value(json(5), p), "");

  p = record(static_cast<wire::ParamKind>(9));
  EXPECT_NE(check_param_value(json(5), p).find("unknown kind"), std::string::npos);
}

// The components message's "latency": the LATENCY reply's buckets as two arrays of
// bucket_count entries; a reply that does not add up is refused with the reason.
TEST(GuiProtocolTest, LatencyHistogramBecomesJsonOnlyWhenItAddsUp) {
  wire::LatencyHistogram h;
  h.data_task = 1;
  h.bucket_count = static_cast<uint32_t>(wire::kLatencyBuckets);
  h.period_ns = 10'000'000;
  h.overruns = 2;
  for (std::size_t j = 0; j < wire::kLatencyBuckets; ++j) h.lower_ns[j] = wire::kLatencyLowerNs[j];
  h.counts[3] = 100;
  h.counts[36] = 2;  // two 5 ms wake-ups
  h.samples = 102;
  h.p99_ns = 4'000;
  auto v = latency_json(h);
  ASSERT_TRUE(std::holds_alternative<nlohmann::json>(v)) << std::get<std::string>(v);
  const auto& j = std::get<nlohmann::json>(v);
  EXPECT_EQ(j["samples"], 102);
  EXPECT_EQ(j["overruns"], 2);
  EXPECT_EQ(j["period_ns"], 10'000'000);
  EXPECT_EQ(j["latency_ns"]["p99"], 4'000);
  ASSERT_EQ(j["lower_ns"].size(), wire::kLatencyBuckets);
  ASSERT_EQ(j["counts"].size(), wire::kLatencyBuckets);
  EXPECT_EQ(j["lower_ns"][36], 5'000'000);
  EXPECT_EQ(j["counts"][36], 2);
  EXPECT_EQ(j["lower_ns"][39], 10'000'000);

  h.samples = 103;
  v = latency_json(h);
  ASSERT_TRUE(std::holds_alternative<std::string>(v));
  EXPECT_EQ(std::get<std::string>(v), "bucket counts do not add up to samples");
  h.samples = 102;
  h.bucket_count = 99;
  v = latency_json(h);
  ASSERT_TRUE(std::holds_alternative<std::string>(v));
  EXPECT_EQ(std::get<std::string>(v), "bucket_count is not 1..40");
}

}  // namespace
}  // namespace rack::gui

namespace rack::gui {
namespace {

ParseError refusal(std::string_view text) {
  auto r = parse_request(text);
  if (!std::holds_alternative<ParseError>(r)) {
    ADD_FAILURE() << std::string(text.substr(0, 200)) << " was accepted";
    return {};
  }
  return std::get<ParseError>(r);
}

TEST(GuiProtocolTest, RefusesHostileMessagesWithTheirReason) {
  // Too large: refused before parsing.
  std::string big = R"j({"op":"all_off","system":0,"pad":")j" + std::string(kMaxRequestBytes, ' ') + "\"}";
  auto e = refusal(big);
  EXPECT_EQ(e.reason, Refusal::kTooLarge);
  EXPECT_NE(e.message.find(std::to_string(big.size()) + " bytes"), std::string::npos) << e.message;
  // Not JSON: where.
  e = refusal(R"j({"op":"all_off",,"system":0})j");
  EXPECT_EQ(e.reason, Refusal::kNotJson);
  EXPECT_NE(e.message.find("at byte 17"), std::string::npos) << e.message;
  e = refusal("{\"op\":\"all_off\",\"system\":0,\"x\":\"\xff\"}");
  EXPECT_EQ(e.reason, Refusal::kNotJson) << "invalid UTF-8";
  e = refusal(std::string_view("{\"op\":\"all\0off\"}", 16));
  EXPECT_EQ(e.reason, Refusal::kNotJson) << "a raw NUL in a string";
  e = refusal(R"j({"op":"set_pose","system":0,"x":1e400,"y":0,"phi":0})j");
  EXPECT_EQ(e.reason, Refusal::kNotJson) << e.message;
  // Nesting: bounded while parsing.
  e = refusal(std::string(100000 / 2, '[') + std::string(100000 / 2, ']'));
  EXPECT_EQ(e.reason, Refusal::kTooLarge);
  EXPECT_EQ(refusal(std::string(30000, '[') + std::string(30000, ']')).reason, Refusal::kTooDeep);
  e = refusal(std::string(9, '[') + std::string(9, ']'));
  EXPECT_EQ(e.reason, Refusal::kTooDeep) << e.message;
  EXPECT_EQ(refusal(R"j({"op":"all_off","system":0,"x":[[[[[[[[[1]]]]]]]]]})j").reason, Refusal::kTooDeep);
  EXPECT_EQ(refusal(std::string(8, '[') + std::string(8, ']')).reason, Refusal::kNotObject) << "8 levels parse";
  // A key twice: nlohmann would keep the last one silently.
  e = refusal(R"j({"op":"all_off","system":0,"system":1})j");
  EXPECT_EQ(e.reason, Refusal::kDuplicateKey);
  EXPECT_NE(e.message.find("key 'system' given twice"), std::string::npos) << e.message;
  EXPECT_EQ(refusal(R"j({"op":"all_off","op":"all_off","system":0})j").reason, Refusal::kDuplicateKey);
  // The same key in two objects is fine (refused for another reason here).
  EXPECT_EQ(refusal(R"j({"op":"set_param","component":"Pilot(0/0)","name":"x","value":{"op":1}})j").reason,
            Refusal::kBadValue);
  // Integers beyond int64: refused, never wrapped (2^64-1 was -1 before).
  e = refusal(R"j({"op":"all_off","system":18446744073709551615})j");
  EXPECT_EQ(e.reason, Refusal::kBadValue);
  e = refusal(R"j({"op":"all_off","system":0,"id":18446744073709551615})j");
  EXPECT_EQ(e.reason, Refusal::kBadValue);
  EXPECT_FALSE(e.id.has_value());
  EXPECT_EQ(refusal(R"j({"op":"set_param","component":"Pilot(0/0)","name":"n","value":9223372036854775808})j").reason,
            Refusal::kBadValue);
  EXPECT_TRUE(
      std::holds_alternative<Request>(parse_request(R"j({"op":"all_off","system":0,"id":9223372036854775807})j")));
  // Integers JSON writes as numbers beyond uint64 become doubles: not an integer.
  EXPECT_EQ(refusal(R"j({"op":"all_off","system":100000000000000000000})j").reason, Refusal::kBadValue);
  // Ops and keys.
  EXPECT_EQ(refusal("{}").reason, Refusal::kBadOp);
  EXPECT_EQ(refusal(R"j({"op":"all_off"})j").reason, Refusal::kBadKey);
  EXPECT_EQ(refusal(R"j({"op":"all_off","system":0,"force":1})j").reason, Refusal::kBadKey);
  EXPECT_EQ(refusal("[]").reason, Refusal::kNotObject);
  EXPECT_EQ(refusal(R"j({"op":"set_param","component":"Pilot(0/0)","name":"a\u0000b","value":1})j").reason,
            Refusal::kBadValue);
}

TEST(GuiProtocolTest, RefusalsQuoteTheClientsTextCutShortAndPrintable) {
  const std::string op(50000, 'A');
  auto e = refusal(R"j({"op":")j" + op + "\"}");
  EXPECT_EQ(e.reason, Refusal::kBadOp);
  EXPECT_LT(e.message.size(), 200u);
  std::string quoted(kMaxQuoted, 'A');
  quoted.append("...'");
  EXPECT_NE(e.message.find(quoted), std::string::npos) << e.message;
  // Control characters become '?'; a cut never splits a UTF-8 character.
  e = refusal(R"j({"op":"a\nb"})j");
  EXPECT_NE(e.message.find("unknown op 'a?b'"), std::string::npos) << e.message;
  std::string wide;
  for (int i = 0; i < 40; ++i) wide += "\xc3\xa4";  // 80 bytes of 'ä'
  e = refusal(R"j({"op":")j" + wide + "\"}");
  const std::string msg = error_message(e);  // invalid UTF-8 would show as U+FFFD here
  EXPECT_EQ(msg.find("\xef\xbf\xbd"), std::string::npos) << "no character was cut in half: " << msg;
  EXPECT_EQ(nlohmann::json::parse(error_message(e)).at("reason"), "bad_op");
}

TEST(GuiProtocolTest, ArbitraryBytesNeverThrowAndAlwaysGiveAnAnswer) {
  // The fuzz harness (tests/fuzz/fuzz_gui_ws.cpp) does this at scale; here a fixed
  // sample of random and mutated messages.
  uint32_t x = 12345;
  const auto next = [&] { return x = x * 1664525u + 1013904223u; };
  const std::string seeds[] = {R"j({"op":"set_pose","system":0,"x":4.0,"y":7.2,"phi":0.0,"id":3})j",
                               R"j({"op":"set_param","component":"Pilot(0/0)","name":"vx_max","value":0.5})j"};
  for (int i = 0; i < 20000; ++i) {
    std::string m = seeds[i % 2];
    const int edits = 1 + static_cast<int>(next() % 8);
    for (int k = 0; k < edits; ++k) {
      const std::size_t at = next() % (m.size() + 1);
      switch (next() % 3) {
        case 0:
          if (at < m.size()) m[at] = static_cast<char>(next());
          break;
        case 1: m.insert(at, 1, "{}[]\",:0e-9\\u"[next() % 14]); break;
        default:
          if (at < m.size()) m.erase(at, 1);
          break;
      }
    }
    const auto r = parse_request(m);
    if (const auto* e = std::get_if<ParseError>(&r)) {
      ASSERT_FALSE(e->message.empty()) << m;
      ASSERT_TRUE(nlohmann::json::accept(error_message(*e))) << m;
    }
  }
}

TEST(GuiProtocolTest, CommandOpTakesANameAndAnObjectBody) {
  const auto r = ok(R"j({"op":"command_json","component":"MCL(0/0)","command":"INIT","body":{"x":4,"y":7.2},"id":3})j");
  EXPECT_EQ(r.op, Op::kCommandJson);
  EXPECT_EQ(r.command, "INIT");
  EXPECT_EQ(r.body.at("y").get<double>(), 7.2);
  EXPECT_NE(refused(R"j({"op":"command_json","component":"MCL(0/0)","command":"init","body":{}})j")
                .find("not a command name"),
            std::string::npos);
  EXPECT_NE(
      refused(R"j({"op":"command_json","component":"MCL(0/0)","command":"","body":{}})j").find("not a command name"),
      std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command_json","component":"MCL(0/0)","command":"INIT","body":[1]})j").find("key 'body'"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"command_json","component":"MCL(0/0)","command":"INIT"})j").find("missing key 'body'"),
            std::string::npos);
}

TEST(GuiProtocolTest, SubscribeTakesAComponentAndAnOptionalPeriod) {
  auto r = ok(R"j({"op":"subscribe","component":"Scan2D(0/0)","id":4})j");
  EXPECT_EQ(r.op, Op::kSubscribe);
  EXPECT_EQ(r.component, tims::Address::make(0, 0, 0));
  EXPECT_EQ(r.component_class, "Scan2D");  // resolved by the backend, as every component class
  EXPECT_EQ(r.period_ms, 0.0);             // every sample
  r = ok(R"j({"op":"subscribe","component":"Chassis(1/0)","period_ms":100})j");
  EXPECT_EQ(r.period_ms, 100.0);
  r = ok(R"j({"op":"unsubscribe","component":"Chassis(1/0)"})j");
  EXPECT_EQ(r.op, Op::kUnsubscribe);
  EXPECT_EQ(r.component, tims::Address::make(1, 0, 0));
  EXPECT_EQ(r.component_class, "Chassis");
  EXPECT_NE(refused(R"j({"op":"subscribe","component":"Scan2D(0/0)","period_ms":-1})j").find("period_ms"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"subscribe","component":"Scan2D(0/0)","period_ms":1e9})j").find("period_ms"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"subscribe","component":"Scan2D(0/0)","period_ms":"0"})j").find("expected a number"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"subscribe","period_ms":0})j").find("missing key 'component'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"unsubscribe","component":"Scan2D(0/0)","period_ms":0})j").find("unknown key"),
            std::string::npos);
}

TEST(GuiProtocolTest, CommandBodyIsEncodedOnlyWhenEveryFieldFits) {
  TypeDescription t;
  t.name = "Body";
  t.fields = {{"x", tims::FieldKind::kF64, 0, 1, ""},
              {"n", tims::FieldKind::kU8, 8, 1, ""},
              {"v", tims::FieldKind::kF32, 12, 3, ""},
              {"label", tims::FieldKind::kChar, 24, 8, ""}};
  t.size = 32;
  std::vector<std::byte> out;
  ASSERT_EQ(encode_command_body(nlohmann::json::parse(R"({"x":1.5,"n":7,"v":[1,2],"label":"ab"})"), &t, out), "");
  ASSERT_EQ(out.size(), 32u);
  double x = 0;
  float v[3] = {9, 9, 9};
  std::memcpy(&x, out.data(), sizeof x);
  std::memcpy(v, out.data() + 12, sizeof v);
  EXPECT_EQ(x, 1.5);
  EXPECT_EQ(static_cast<uint8_t>(out[8]), 7u);
  EXPECT_EQ(v[0], 1.0F);
  EXPECT_EQ(v[1], 2.0F);
  EXPECT_EQ(v[2], 0.0F);  // left out: 0
  EXPECT_EQ(std::memcmp(out.data() + 24, "ab\0", 3), 0);

  EXPECT_NE(encode_command_body(nlohmann::json::parse(R"({"z":1})"), &t, out).find("field 'z': Body has no such field"),
            std::string::npos);
  EXPECT_NE(encode_command_body(nlohmann::json::parse(R"({"n":300})"), &t, out).find("field 'n'"), std::string::npos);
  EXPECT_NE(encode_command_body(nlohmann::json::parse(R"({"v":[1,2,3,4]})"), &t, out).find("4 elements, at most 3"),
            std::string::npos);
  EXPECT_NE(encode_command_body(nlohmann::json::parse(R"({"x":{"a":1}})"), &t, out).find("got object"),
            std::string::npos);
  EXPECT_NE(encode_command_body(nlohmann::json::parse(R"({"label":"far too long"})"), &t, out).find("field 'label'"),
            std::string::npos);
  // A command without a body takes only an empty one.
  EXPECT_EQ(encode_command_body(nlohmann::json::object(), nullptr, out), "");
  EXPECT_NE(encode_command_body(nlohmann::json::parse(R"({"x":1})"), nullptr, out).find("takes no body"),
            std::string::npos);
}

}  // namespace
}  // namespace rack::gui
