// rackctl's names of enum and address fields, beside the raw values of a sample.
#include <gtest/gtest.h>

#include <span>
#include <string>

#include "field_names.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"
#include "rack/tims/address.h"

namespace rack::tools {
namespace {

template <typename T>
std::span<const std::byte> bytes_of(const T& v) {
  return {reinterpret_cast<const std::byte*>(&v), sizeof v};
}

TEST(FieldNamesTest, PilotModeAndStatusByName) {
  interfaces::PilotData d;
  d.mode = static_cast<uint8_t>(interfaces::PilotMode::kDestination);
  d.status = static_cast<uint8_t>(interfaces::PilotStatus::kBlocked);
  EXPECT_EQ(field_names_json(tims::classes::kPilot, tims::fields_of<interfaces::PilotData>, bytes_of(d), true),
            "{\"mode\":\"DESTINATION\",\"status\":\"BLOCKED\"}");
  d.status = 42;  // a value this rackctl does not know
  EXPECT_EQ(field_names_json(tims::classes::kPilot, tims::fields_of<interfaces::PilotData>, bytes_of(d), true),
            "{\"mode\":\"DESTINATION\",\"status\":\"UNKNOWN(42)\"}");
}

TEST(FieldNamesTest, ActivePilotAsAnAddressInEitherByteOrder) {
  interfaces::ChassisData d;
  const tims::Address pilot(0x00190000u);  // Pilot(0/0): class 0x19
  d.active_pilot = pilot.raw();
  const std::string want = "{\"active_pilot\":\"" + pilot.str() + "\"}";
  EXPECT_EQ(field_names_json(tims::classes::kChassis, tims::fields_of<interfaces::ChassisData>, bytes_of(d), true),
            want);
  EXPECT_NE(want.find("Pilot("), std::string::npos) << want;
  d.active_pilot = __builtin_bswap32(pilot.raw());  // sent by a host of the other byte order
  EXPECT_EQ(field_names_json(tims::classes::kChassis, tims::fields_of<interfaces::ChassisData>, bytes_of(d), false),
            want);
  d.active_pilot = 0;
  EXPECT_EQ(field_names_json(tims::classes::kChassis, tims::fields_of<interfaces::ChassisData>, bytes_of(d), true),
            "{\"active_pilot\":\"none\"}");
}

TEST(FieldNamesTest, OtherClassesAndShortSamplesHaveNoNames) {
  interfaces::PilotData d;
  // The same layout under another class: no names.
  EXPECT_EQ(field_names_json(tims::classes::kPath, tims::fields_of<interfaces::PilotData>, bytes_of(d), true), "");
  // A sample cut before the fields: nothing read past its end.
  EXPECT_EQ(field_names_json(tims::classes::kPilot, tims::fields_of<interfaces::PilotData>, bytes_of(d).first(8), true),
            "");
  EXPECT_STREQ(enum_value_name(tims::classes::kPilot, "status", 2), "REACHED");
  EXPECT_EQ(enum_value_name(tims::classes::kPilot, "target_x", 2), nullptr);
}

}  // namespace
}  // namespace rack::tools
