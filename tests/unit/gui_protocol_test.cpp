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
  EXPECT_EQ(r.component, tims::Address::make(0, tims::classes::kChassis, 0));
  EXPECT_TRUE(r.on);
  ASSERT_TRUE(r.id.has_value());
  EXPECT_EQ(*r.id, 7);

  r = ok(R"j({"op":"all_off","system":3})j");
  EXPECT_EQ(r.op, Op::kAllOff);
  EXPECT_EQ(r.system, 3);
  EXPECT_FALSE(r.id.has_value());

  r = ok(R"j({"op":"get_params","component":"Pilot(1/2)"})j");
  EXPECT_EQ(r.component, tims::Address::make(1, tims::classes::kPilot, 2));

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
  EXPECT_NE(refused(R"j({"op":"switch","component":"Chassis(0/0)","on":"yes"})j").find("key 'on': expected true or false, got string"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":"Chassis(0/0)","on":1})j").find("got integer"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":17,"on":true})j").find("key 'component'"), std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":"chassis","on":true})j").find("'chassis' is not an address"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"switch","component":"Chassis(0/0)#3","on":true})j").find("names a mailbox"),
            std::string::npos);
  EXPECT_NE(refused(R"j({"op":"set_destination","system":0,"x":"10","y":8})j").find("key 'x': expected a number, got string"),
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
