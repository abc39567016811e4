// Parameters: declaration, text and wire setters, ranges, strings.
#include "rack/core/parameters.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace rack {
namespace {

class ParametersTest : public ::testing::Test {
 protected:
  ParametersTest()
      : i_(set_.declare_int("count", 5, {.doc = "an int", .min = 0, .max = 10})),
        f_(set_.declare_float("gain", 1.5, {.doc = "a float", .min = -2.0, .max = 2.0})),
        b_(set_.declare_bool("verbose", true)),
        s_(set_.declare_string("label", "hello")) {}

  static wire::ParamRecord record(ParamKind kind, int64_t iv, double fv = 0.0, const char* text = "") {
    wire::ParamRecord r;
    r.kind = static_cast<uint8_t>(kind);
    r.int_value = iv;
    r.float_value = fv;
    wire::copy_text(r.string_value, text);
    return r;
  }

  ParameterSet set_;
  Parameter& i_;
  Parameter& f_;
  Parameter& b_;
  Parameter& s_;
};

TEST_F(ParametersTest, DeclaresEachKindWithItsInitialValue) {
  EXPECT_EQ(set_.size(), 4u);
  EXPECT_EQ(i_.kind(), ParamKind::kInt);
  EXPECT_EQ(f_.kind(), ParamKind::kFloat);
  EXPECT_EQ(b_.kind(), ParamKind::kBool);
  EXPECT_EQ(s_.kind(), ParamKind::kString);
  EXPECT_EQ(i_.get_int(), 5);
  EXPECT_DOUBLE_EQ(f_.get_float(), 1.5);
  EXPECT_TRUE(b_.get_bool());
  EXPECT_EQ(s_.get_string(), "hello");
  EXPECT_EQ(set_.find("gain"), &f_);
  EXPECT_EQ(set_.find("nope"), nullptr);
  EXPECT_EQ(set_.names(), "count, gain, verbose, label");
  EXPECT_EQ(i_.spec().doc, "an int");
}

TEST_F(ParametersTest, SetFromTextAcceptsValidValues) {
  EXPECT_FALSE(i_.set_from_text("7").has_value());
  EXPECT_EQ(i_.get_int(), 7);
  EXPECT_FALSE(i_.set_from_text("0x0A").has_value());  // base prefixes are accepted
  EXPECT_EQ(i_.get_int(), 10);
  EXPECT_FALSE(f_.set_from_text("-0.25").has_value());
  EXPECT_DOUBLE_EQ(f_.get_float(), -0.25);
  EXPECT_FALSE(f_.set_from_text("2").has_value());
  EXPECT_DOUBLE_EQ(f_.get_float(), 2.0);
  for (const char* yes : {"true", "on", "yes"}) {
    EXPECT_FALSE(b_.set_from_text("false").has_value());
    EXPECT_FALSE(b_.set_from_text(yes).has_value());
    EXPECT_TRUE(b_.get_bool()) << yes;
  }
  for (const char* no : {"false", "off", "no"}) {
    EXPECT_FALSE(b_.set_from_text("true").has_value());
    EXPECT_FALSE(b_.set_from_text(no).has_value());
    EXPECT_FALSE(b_.get_bool()) << no;
  }
  EXPECT_FALSE(s_.set_from_text("with spaces and ünïcode").has_value());
  EXPECT_EQ(s_.get_string(), "with spaces and ünïcode");
  EXPECT_TRUE(s_.was_set());
}

TEST_F(ParametersTest, SetFromTextRejectsInvalidValuesAndNamesTheParameter) {
  struct Case {
    Parameter* p;
    const char* text;
  };
  for (const Case c : {Case{&i_, "abc"}, Case{&i_, ""}, Case{&i_, "3.5"}, Case{&i_, "7x"},
                       Case{&i_, "99999999999999999999999"}, Case{&f_, "fast"}, Case{&f_, ""}, Case{&f_, "nan"},
                       Case{&f_, "inf"}, Case{&b_, "maybe"}, Case{&b_, "1"}, Case{&b_, "TRUE "}}) {
    const auto err = c.p->set_from_text(c.text);
    ASSERT_TRUE(err.has_value()) << c.p->name() << " accepted '" << c.text << "'";
    EXPECT_NE(err->find("'" + c.p->name() + "'"), std::string::npos) << *err;
  }
  // Nothing changed.
  EXPECT_EQ(i_.get_int(), 5);
  EXPECT_DOUBLE_EQ(f_.get_float(), 1.5);
  EXPECT_TRUE(b_.get_bool());
}

TEST_F(ParametersTest, RangesAreEnforcedFromTextAndWire) {
  auto err = i_.set_from_text("11");
  ASSERT_TRUE(err.has_value());
  EXPECT_NE(err->find("'count'"), std::string::npos) << *err;
  EXPECT_NE(err->find("[0, 10]"), std::string::npos) << *err;
  EXPECT_TRUE(i_.set_from_text("-1").has_value());
  EXPECT_FALSE(i_.set_from_text("10").has_value());  // bounds are inclusive
  EXPECT_FALSE(i_.set_from_text("0").has_value());
  err = f_.set_from_text("2.5");
  ASSERT_TRUE(err.has_value());
  EXPECT_NE(err->find("'gain'"), std::string::npos);
  EXPECT_NE(i_.set_from_wire(record(ParamKind::kInt, 11)), nullptr);
  EXPECT_NE(f_.set_from_wire(record(ParamKind::kFloat, 0, -2.01)), nullptr);
  EXPECT_EQ(i_.get_int(), 0);
  EXPECT_DOUBLE_EQ(f_.get_float(), 1.5);
}

TEST_F(ParametersTest, SetFromWireRefusesAKindMismatchWithAReason) {
  const char* why = i_.set_from_wire(record(ParamKind::kFloat, 0, 3.0));
  ASSERT_NE(why, nullptr);
  EXPECT_NE(std::string(why).find("type"), std::string::npos) << why;
  EXPECT_NE(b_.set_from_wire(record(ParamKind::kInt, 1)), nullptr);
  EXPECT_NE(s_.set_from_wire(record(ParamKind::kInt, 1)), nullptr);
  EXPECT_NE(f_.set_from_wire(record(ParamKind::kString, 0, 0.0, "1.0")), nullptr);
  EXPECT_NE(f_.set_from_wire(record(ParamKind::kBool, 1)), nullptr);
  EXPECT_NE(b_.set_from_wire(record(ParamKind::kBool, 2)), nullptr);  // a bool is 0 or 1
  EXPECT_EQ(i_.get_int(), 5);
  EXPECT_TRUE(b_.get_bool());
  EXPECT_EQ(s_.get_string(), "hello");
}

TEST_F(ParametersTest, SetFromWireAcceptsAnIntForAFloat) {
  EXPECT_EQ(f_.set_from_wire(record(ParamKind::kInt, -2)), nullptr);
  EXPECT_DOUBLE_EQ(f_.get_float(), -2.0);
  EXPECT_EQ(f_.set_from_wire(record(ParamKind::kFloat, 0, 0.125)), nullptr);
  EXPECT_DOUBLE_EQ(f_.get_float(), 0.125);
  EXPECT_EQ(i_.set_from_wire(record(ParamKind::kInt, 3)), nullptr);
  EXPECT_EQ(i_.get_int(), 3);
  EXPECT_EQ(b_.set_from_wire(record(ParamKind::kBool, 0)), nullptr);
  EXPECT_FALSE(b_.get_bool());
}

TEST_F(ParametersTest, StringRoundTripsThroughWireRecords) {
  ASSERT_EQ(s_.set_from_wire(record(ParamKind::kString, 0, 0.0, "front/left")), nullptr);
  EXPECT_EQ(s_.get_string(), "front/left");
  wire::ParamRecord out;
  s_.to_record(out);
  EXPECT_STREQ(out.name, "label");
  EXPECT_EQ(out.kind, static_cast<uint8_t>(ParamKind::kString));
  EXPECT_STREQ(out.string_value, "front/left");
  // A shorter string replaces the longer one completely.
  ASSERT_EQ(s_.set_from_wire(record(ParamKind::kString, 0, 0.0, "ab")), nullptr);
  s_.to_record(out);
  EXPECT_STREQ(out.string_value, "ab");
  // An unterminated string is refused.
  wire::ParamRecord bad = record(ParamKind::kString, 0);
  std::memset(bad.string_value, 'x', sizeof bad.string_value);
  EXPECT_NE(s_.set_from_wire(bad), nullptr);
  EXPECT_EQ(s_.get_string(), "ab");
  // The longest string that fits (127 characters) round-trips; 128 is refused.
  const std::string longest(wire::kParamStringLen - 1, 'z');
  EXPECT_FALSE(s_.set_from_text(longest).has_value());
  EXPECT_EQ(s_.get_string(), longest);
  const auto err = s_.set_from_text(std::string(wire::kParamStringLen, 'z'));
  ASSERT_TRUE(err.has_value());
  EXPECT_NE(err->find("'label'"), std::string::npos);
}

TEST_F(ParametersTest, RecordsCarryEachKindsValue) {
  wire::ParamRecord r;
  i_.to_record(r);
  EXPECT_STREQ(r.name, "count");
  EXPECT_EQ(r.kind, static_cast<uint8_t>(ParamKind::kInt));
  EXPECT_EQ(r.int_value, 5);
  f_.to_record(r);
  EXPECT_EQ(r.kind, static_cast<uint8_t>(ParamKind::kFloat));
  EXPECT_DOUBLE_EQ(r.float_value, 1.5);
  b_.to_record(r);
  EXPECT_EQ(r.kind, static_cast<uint8_t>(ParamKind::kBool));
  EXPECT_EQ(r.int_value, 1);
  EXPECT_EQ(r.flags, 0);
  EXPECT_EQ(f_.value_text(), "1.5");
  EXPECT_EQ(b_.value_text(), "true");
}

TEST_F(ParametersTest, CopyStringTruncatesAndAlwaysTerminates) {
  ASSERT_FALSE(s_.set_from_text("abcdef").has_value());
  char buf[16];
  std::memset(buf, 'X', sizeof buf);
  s_.copy_string(buf, 4);
  EXPECT_STREQ(buf, "abc");
  EXPECT_EQ(buf[4], 'X') << "wrote past the given size";
  s_.copy_string(buf, 1);
  EXPECT_STREQ(buf, "");
  s_.copy_string(buf, 7);
  EXPECT_STREQ(buf, "abcdef");
  s_.copy_string(buf, 6);
  EXPECT_STREQ(buf, "abcde");
  s_.copy_string(buf, sizeof buf);
  EXPECT_STREQ(buf, "abcdef");
  s_.copy_string(buf, 0);  // nothing written, no crash
  EXPECT_STREQ(buf, "abcdef");
}

TEST_F(ParametersTest, DuplicateOrBadNamesThrow) {
  EXPECT_THROW(set_.declare_int("count", 1), std::invalid_argument);
  EXPECT_THROW(set_.declare_string("gain", "x"), std::invalid_argument);  // another kind, same name
  EXPECT_THROW(set_.declare_bool("", false), std::invalid_argument);
  EXPECT_THROW(set_.declare_bool(std::string(wire::kParamNameLen, 'n'), false), std::invalid_argument);
  EXPECT_NO_THROW(set_.declare_bool(std::string(wire::kParamNameLen - 1, 'n'), false));
  EXPECT_EQ(set_.size(), 5u);
  EXPECT_THROW(set_.declare_string("too_long_default", std::string(200, 'x')), std::invalid_argument);
}

TEST_F(ParametersTest, ComponentReferenceCannotChangeAtRunTime) {
  Parameter& ref = set_.declare_string("source", "", {.doc = "a reference", .required = true, .component_ref = true});
  EXPECT_FALSE(ref.set_from_text("generator").has_value());
  EXPECT_NE(ref.set_from_wire(record(ParamKind::kString, 0, 0.0, "other")), nullptr);
  EXPECT_EQ(ref.get_string(), "generator");
  wire::ParamRecord r;
  ref.to_record(r);
  EXPECT_EQ(r.flags & 1, 1);
}

// Paths (issue 21 item 3): relative to the host file's folder in the host file and in
// SET_PARAM alike, stored absolute.
TEST(ParameterPathsTest, ARelativePathIsStoredAgainstTheBaseFolder) {
  ParameterSet set;
  Parameter& map = set.declare_string("map", "", {.doc = "a path", .path = PathRole::kInput});
  Parameter& out = set.declare_string("store_dir", ".", {.doc = "a path", .path = PathRole::kOutputDir});
  Parameter& label = set.declare_string("label", "a/b");
  // Before the base is set (a component made outside a host file): as given.
  EXPECT_EQ(out.get_string(), ".");
  for (std::size_t i = 0; i < set.size(); ++i) EXPECT_FALSE(set.at(i).set_base_dir("/robot/configs").has_value());
  EXPECT_EQ(out.get_string(), "/robot/configs");  // the declared default too
  EXPECT_EQ(label.get_string(), "a/b");           // not a path
  EXPECT_EQ(map.get_string(), "");                // empty stays empty (none)
  ASSERT_FALSE(map.set_from_text("maps/office.yaml").has_value());
  EXPECT_EQ(map.get_string(), "/robot/configs/maps/office.yaml");
  ASSERT_FALSE(map.set_from_text("./maps/../maps/office.yaml").has_value());
  EXPECT_EQ(map.get_string(), "/robot/configs/maps/../maps/office.yaml");
  ASSERT_FALSE(map.set_from_text("/abs/office.yaml").has_value());
  EXPECT_EQ(map.get_string(), "/abs/office.yaml");
  EXPECT_EQ(resolve_path("/robot/configs", "scans/a.pcd"), "/robot/configs/scans/a.pcd");
  EXPECT_EQ(resolve_path("/", "a"), "/a");
  EXPECT_EQ(resolve_path("", "a"), "a");
}

TEST(ParameterPathsTest, SetParamResolvesAgainstTheHostFilesFolderNotTheSenders) {
  ParameterSet set;
  Parameter& out = set.declare_string("store_dir", ".", {.doc = "a path", .path = PathRole::kOutputDir});
  Parameter& dev = set.declare_string("device", "", {.doc = "a path", .path = PathRole::kDevice});
  ASSERT_FALSE(out.set_base_dir("/robot").has_value());
  ASSERT_FALSE(dev.set_base_dir("/robot").has_value());
  wire::ParamRecord r;
  r.kind = static_cast<uint8_t>(ParamKind::kString);
  wire::copy_text(r.string_value, "scans");
  ASSERT_EQ(out.set_from_wire(r), nullptr);
  EXPECT_EQ(out.get_string(), "/robot/scans");
  // check_wire shows the class's rules the value as it will be stored.
  wire::ParamRecord v;
  wire::copy_text(r.string_value, "./x");
  ASSERT_EQ(out.check_wire(r, v), nullptr);
  EXPECT_STREQ(v.string_value, "/robot/x");
  // A device number stays a number; a relative device path is resolved.
  wire::copy_text(r.string_value, "0");
  ASSERT_EQ(dev.set_from_wire(r), nullptr);
  EXPECT_EQ(dev.get_string(), "0");
  wire::copy_text(r.string_value, "dev/ttyX");
  ASSERT_EQ(dev.set_from_wire(r), nullptr);
  EXPECT_EQ(dev.get_string(), "/robot/dev/ttyX");
}

TEST(ParameterPathsTest, AnAbsolutePathThatDoesNotFitIsRefusedWithIt) {
  ParameterSet set;
  Parameter& map = set.declare_string("map", "", {.doc = "a path", .path = PathRole::kInput});
  const std::string base = "/" + std::string(100, 'd');
  ASSERT_FALSE(map.set_base_dir(base).has_value());
  const std::string rel(40, 'm');  // fits alone, not behind the base
  const auto err = map.set_from_text(rel);
  ASSERT_TRUE(err.has_value());
  EXPECT_NE(err->find(base + "/" + rel), std::string::npos) << *err;
  EXPECT_NE(err->find("longer than 127"), std::string::npos) << *err;
  wire::ParamRecord r;
  r.kind = static_cast<uint8_t>(ParamKind::kString);
  wire::copy_text(r.string_value, rel.c_str());
  EXPECT_NE(map.set_from_wire(r), nullptr);
  EXPECT_EQ(map.get_string(), "");  // unchanged
}

}  // namespace
}  // namespace rack
