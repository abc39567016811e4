// set_field_from_text: how rackctl send (and any tool) turns FIELD=VALUE text into a
// command body through the body's field table.
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <span>
#include <string>

#include "rack/core/payload_json.h"
#include "mcl/mcl_types.h"
#include "rack/interfaces/robot.h"
#include "rack/interfaces/navigation.h"
#include "rack/tims/payload.h"

namespace rack {
namespace {

struct Mixed {
  int8_t small = 0;
  uint16_t port = 0;
  uint32_t address = 0;
  float ratio = 0.0f;
  bool flag = false;
  char label[8] = {};
  int32_t values[3] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(Mixed, small), RACK_FIELD(Mixed, port), RACK_FIELD(Mixed, address),
                      RACK_FIELD(Mixed, ratio), RACK_FIELD(Mixed, flag), RACK_FIELD(Mixed, label),
                      RACK_FIELD(Mixed, values)};
  }
};

const tims::FieldDesc& field(const char* name) {
  for (const auto& f : tims::fields_of<Mixed>) {
    if (std::strcmp(f.name, name) == 0) return f;
  }
  throw std::logic_error(name);
}

std::span<std::byte> bytes(Mixed& m) { return {reinterpret_cast<std::byte*>(&m), sizeof m}; }

// JSON text is UTF-8: a char array's bytes that are not (a sender's garbage) become
// U+FFFD; well-formed sequences pass (found by fuzz_payload: rack-gui dropped the sample).
TEST(JsonEscape, KeepsWellFormedUtf8AndReplacesInvalidBytes) {
  EXPECT_EQ(json_escape("gr\xc3\xbc\xc3\x9f \xe2\x82\xac \xf0\x9f\xa4\x96"),
            "gr\xc3\xbc\xc3\x9f \xe2\x82\xac \xf0\x9f\xa4\x96");
  EXPECT_EQ(json_escape("the\xad*reason"), "the\\ufffd*reason");
  EXPECT_EQ(json_escape("\xc3"), "\\ufffd");                        // cut sequence
  EXPECT_EQ(json_escape("\xc0\xaf"), "\\ufffd\\ufffd");             // overlong '/'
  EXPECT_EQ(json_escape("\xed\xa0\x80"), "\\ufffd\\ufffd\\ufffd");  // a surrogate
  EXPECT_EQ(json_escape("a\"b\\\x01"), "a\\\"b\\\\\\u0001");
}

TEST(SetFieldFromText, SetsEachKind) {
  Mixed m;
  EXPECT_EQ(set_field_from_text(field("small"), bytes(m), "-12"), "");
  EXPECT_EQ(set_field_from_text(field("port"), bytes(m), "+7667"), "");
  EXPECT_EQ(set_field_from_text(field("address"), bytes(m), "0x190000"), "");
  EXPECT_EQ(set_field_from_text(field("ratio"), bytes(m), "0.25"), "");
  EXPECT_EQ(set_field_from_text(field("flag"), bytes(m), "true"), "");
  EXPECT_EQ(set_field_from_text(field("label"), bytes(m), "front"), "");
  EXPECT_EQ(set_field_from_text(field("values"), bytes(m), "1,-2"), "");
  EXPECT_EQ(m.small, -12);
  EXPECT_EQ(m.port, 7667);
  EXPECT_EQ(m.address, 0x190000u);
  EXPECT_FLOAT_EQ(m.ratio, 0.25f);
  EXPECT_TRUE(m.flag);
  EXPECT_STREQ(m.label, "front");
  EXPECT_EQ(m.values[0], 1);
  EXPECT_EQ(m.values[1], -2);
  EXPECT_EQ(m.values[2], 0) << "elements not given keep their value";
}

TEST(SetFieldFromText, RefusesWhatDoesNotFitAndLeavesThePayloadAlone) {
  Mixed m;
  m.small = 5;
  m.values[0] = 9;
  EXPECT_EQ(set_field_from_text(field("small"), bytes(m), "200"), "'200' is outside -128..127");
  EXPECT_EQ(set_field_from_text(field("small"), bytes(m), "1.5"), "'1.5' is not an integer");
  EXPECT_EQ(set_field_from_text(field("small"), bytes(m), ""), "'' is not an integer");
  EXPECT_EQ(set_field_from_text(field("small"), bytes(m), "+-5"), "'+-5' is not an integer");
  EXPECT_EQ(set_field_from_text(field("label"), bytes(m), std::string("ab\0c", 4)),
            "a text with a NUL character would be cut there");
  EXPECT_EQ(set_field_from_text(field("port"), bytes(m), "-1"), "'-1' is not an unsigned integer");
  EXPECT_EQ(set_field_from_text(field("port"), bytes(m), "70000"), "'70000' is outside 0..65535");
  EXPECT_EQ(set_field_from_text(field("ratio"), bytes(m), "nan"), "'nan' is not a finite number");
  EXPECT_EQ(set_field_from_text(field("ratio"), bytes(m), "1e300"), "'1e300' does not fit a float");
  EXPECT_EQ(set_field_from_text(field("flag"), bytes(m), "yes"), "'yes' is not a bool (true, false, 1 or 0)");
  EXPECT_EQ(set_field_from_text(field("label"), bytes(m), "eightchr"),
            "a text of at most 7 characters is needed, got 8");
  EXPECT_EQ(set_field_from_text(field("values"), bytes(m), "1,2,3,4"), "at most 3 elements fit, got more");
  EXPECT_EQ(set_field_from_text(field("values"), bytes(m), "1,x"), "element 1: 'x' is not an integer");
  EXPECT_EQ(m.small, 5);
  EXPECT_EQ(m.values[0], 9) << "a bad element leaves the whole array as it was";
  EXPECT_FALSE(m.flag);
  EXPECT_EQ(m.label[0], '\0');
}

TEST(SetFieldFromText, BuildsAnMclInitBody) {
  interfaces::MclInit init;
  std::span<std::byte> body(reinterpret_cast<std::byte*>(&init), sizeof init);
  for (const auto& f : tims::fields_of<interfaces::MclInit>) {
    const std::string name = f.name;
    const char* text = name == "x" ? "2" : name == "y" ? "1.5" : name == "global" ? "1" : "0.3";
    ASSERT_EQ(set_field_from_text(f, body, text), "") << name;
  }
  EXPECT_DOUBLE_EQ(init.x, 2.0);
  EXPECT_DOUBLE_EQ(init.y, 1.5);
  EXPECT_DOUBLE_EQ(init.sigma_xy, 0.3);
  EXPECT_EQ(init.global, 1);
}

}  // namespace
}  // namespace rack

namespace rack {
namespace {

// Numbers for people: the shortest text that reads back as the same value, not 9 or
// 17 significant digits of binary noise.
TEST(PayloadToJson, FloatsAreShortestRoundTrip) {
  struct Floats {
    float f = 0.1f;
    double d = 0.3;
    double big = 1e300;
    static constexpr auto fields() noexcept {
      return std::array{RACK_FIELD(Floats, f), RACK_FIELD(Floats, d), RACK_FIELD(Floats, big)};
    }
  };
  Floats v;
  const std::string j = payload_to_json(
      tims::fields_of<Floats>, std::span<const std::byte>(reinterpret_cast<const std::byte*>(&v), sizeof v), true);
  EXPECT_EQ(j, "{\"f\": 0.1, \"d\": 0.3, \"big\": 1e+300}");
}

}  // namespace
}  // namespace rack
