// rackctl's names of enum and address fields, beside the raw values of a sample.
#include <gtest/gtest.h>

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "field_names.h"
#include "rack/core/registry.h"
#include "gps_nmea/gps_nmea_types.h"
#include "pilot/pilot_types.h"
#include "rack/interfaces/declared_types.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"
#include "rack/tims/address.h"

namespace rack::tools {
namespace {

template <typename T>
std::span<const std::byte> bytes_of(const T& v) {
  return {reinterpret_cast<const std::byte*>(&v), sizeof v};
}

// The value names of a data type as its class's description carries them: declared
// with the class (components/pilot/pilot_types.h), through the encoder and decoder.
std::vector<FieldNamesDescription> described_names(const DataTypeInfo& type) {
  ComponentClass cls;
  cls.impl = "NamesTest";
  cls.class_id = 0xA9;
  cls.description = "names";
  cls.data = &type;
  ClassDescription d = describe_class(cls, ParameterSet{});
  ClassDescription back;
  std::string error;
  EXPECT_TRUE(decode_class_description(encode_class_description(d), back, error)) << error;
  return back.value_names;
}

TEST(FieldNamesTest, PilotModeAndStatusByName) {
  const auto names = described_names(components::kPilotType);
  interfaces::PilotData d;
  d.mode = static_cast<uint8_t>(interfaces::PilotMode::kDestination);
  d.status = static_cast<uint8_t>(interfaces::PilotStatus::kBlocked);
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::PilotData>, bytes_of(d), true),
            "{\"mode\":\"DESTINATION\",\"status\":\"BLOCKED\"}");
  d.status = 42;  // a value the class does not name
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::PilotData>, bytes_of(d), true),
            "{\"mode\":\"DESTINATION\",\"status\":\"UNKNOWN(42)\"}");
}

TEST(FieldNamesTest, ActivePilotAsAnAddressInEitherByteOrder) {
  const auto names = described_names(interfaces::declared::kChassis);
  interfaces::ChassisData d;
  const tims::Address pilot(0x00190000u);  // Pilot(0/0): class 0x19
  d.active_pilot = pilot.raw();
  const std::string want = "{\"active_pilot\":\"" + pilot.str() + "\"}";
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::ChassisData>, bytes_of(d), true), want);
  EXPECT_NE(want.find("Pilot("), std::string::npos) << want;
  d.active_pilot = __builtin_bswap32(pilot.raw());  // sent by a host of the other byte order
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::ChassisData>, bytes_of(d), false), want);
  d.active_pilot = 0;
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::ChassisData>, bytes_of(d), true),
            "{\"active_pilot\":\"none\"}");
}

// The tools link no class: they name an address field's component by the class that
// component describes, through their own namer, which gets the component's command
// address (not the mailbox the field holds).
TEST(FieldNamesTest, AddressFieldsThroughTheToolsNamer) {
  const auto names = described_names(interfaces::declared::kChassis);
  interfaces::ChassisData d;
  d.active_pilot = tims::Address::make(2, 0x91, 1, 3).raw();  // a plug-in's mailbox 3
  std::vector<tims::Address> asked;
  const AddressNamer namer = [&asked](tims::Address a) {
    asked.push_back(a);
    return std::string("Counter(") + std::to_string(a.system()) + "/" + std::to_string(a.instance()) + ")";
  };
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::ChassisData>, bytes_of(d), true, namer),
            "{\"active_pilot\":\"Counter(2/1)\"}");
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_EQ(asked[0], tims::Address::make(2, 0x91, 1));
  d.active_pilot = 0;  // none: the namer is not asked
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::ChassisData>, bytes_of(d), true, namer),
            "{\"active_pilot\":\"none\"}");
  EXPECT_EQ(asked.size(), 1u);
}

// Fields read by name (rack-gui's camera image and the chassis' active pilot).
TEST(FieldNamesTest, UnsignedFieldsByName) {
  interfaces::ChassisData d;
  d.active_pilot = 0x00190203u;
  const auto fields = tims::fields_of<interfaces::ChassisData>;
  const tims::FieldDesc* f = find_field(fields, "active_pilot");
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(unsigned_field(*f, bytes_of(d), true), std::optional<uint64_t>(0x00190203u));
  d.active_pilot = __builtin_bswap32(0x00190203u);
  EXPECT_EQ(unsigned_field(*f, bytes_of(d), false), std::optional<uint64_t>(0x00190203u));
  EXPECT_EQ(find_field(fields, "no_such_field"), nullptr);
  // Outside a short sample, or a floating-point field: nothing read.
  EXPECT_EQ(unsigned_field(*f, bytes_of(d).first(f->offset + 2), true), std::nullopt);
  const tims::FieldDesc* vx = find_field(fields, "vx");
  ASSERT_NE(vx, nullptr);
  EXPECT_EQ(unsigned_field(*vx, bytes_of(d), true), std::nullopt);
}

TEST(FieldNamesTest, ClassesWithoutNamesAndShortSamplesHaveNoNames) {
  interfaces::PilotData d;
  // The same layout without value names (a class that declares none): no names.
  EXPECT_EQ(field_names_json({}, tims::fields_of<interfaces::PilotData>, bytes_of(d), true), "");
  // A sample cut before the fields: nothing read past its end.
  const auto names = described_names(components::kPilotType);
  EXPECT_EQ(field_names_json(names, tims::fields_of<interfaces::PilotData>, bytes_of(d).first(8), true), "");
  ASSERT_EQ(names.size(), 2u);
  EXPECT_STREQ(names[1].name_of(2), "REACHED");
  EXPECT_EQ(names[1].name_of(200), nullptr);
  // GPS: names that are not identifiers ("2D").
  const auto gps = described_names(components::kGpsType);
  interfaces::GpsData g;
  g.fix_quality = interfaces::kGpsFixRtkFixed;
  g.fix_mode = 2;
  EXPECT_EQ(field_names_json(gps, tims::fields_of<interfaces::GpsData>, bytes_of(g), true),
            "{\"fix_quality\":\"RTK_FIXED\",\"fix_mode\":\"2D\"}");
}

}  // namespace
}  // namespace rack::tools
