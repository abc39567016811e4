// Class descriptions (rack/core/class_description.h): the codec round-trips and
// refuses malformed input with its offset; pages assemble; a running component
// answers GET_CLASS with its class; every class of the tree, built-in or plug-in, is
// described as declared and its data size is the payload its component publishes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "rack/components/builtin.h"
#include "rack/components/class_ids.h"
#include "rack/core/class_description.h"
#include "rack/core/data_component.h"
#include "rack/core/registry.h"
#include "rack/tims/message.h"
#include "test_support.h"

namespace rack {
namespace {

template <typename T>
std::span<const std::byte> bytes_of(const T& v) {
  return {reinterpret_cast<const std::byte*>(&v), sizeof v};
}

ClassDescription sample_description() {
  ClassDescription d;
  d.impl = "Counter";
  d.class_name = "Counter";
  d.class_id = 0x91;
  d.summary = "test: counts, with a reset command";
  TypeDescription data{"CounterData",
                       24,
                       {{"count", tims::FieldKind::kI64, 0, 1, ""},
                        {"rate", tims::FieldKind::kF64, 8, 1, ""},
                        {"label", tims::FieldKind::kChar, 16, 8, ""}}};
  d.data = data;
  CommandDescription reset{"RESET", 21, "start counting again from `start`",
                           TypeDescription{"CounterReset", 8, {{"start", tims::FieldKind::kI64, 0, 1, ""}}}};
  d.commands.push_back(reset);
  d.commands.push_back({"FREEZE", 22, "stop counting", std::nullopt});
  ParameterDescription step;
  step.name = "step";
  step.kind = wire::ParamKind::kFloat;
  step.unit = "1/s";
  step.min = 0.0;
  step.max = std::numeric_limits<double>::infinity();
  step.default_value = "1";
  step.doc = "how much the count grows per cycle";
  d.parameters.push_back(step);
  ParameterDescription mode;
  mode.name = "mode";
  mode.kind = wire::ParamKind::kString;
  mode.flags = ParameterDescription::kInitOnly | ParameterDescription::kRequired;
  mode.min = -std::numeric_limits<double>::infinity();
  mode.max = std::numeric_limits<double>::infinity();
  mode.default_value = "up";
  mode.doc = "direction";
  mode.choices = {"up", "down"};
  d.parameters.push_back(mode);
  return d;
}

TEST(ClassDescriptionTest, RoundTripsEveryPart) {
  const ClassDescription d = sample_description();
  const std::vector<std::byte> bytes = encode_class_description(d);
  ClassDescription back;
  std::string error;
  ASSERT_TRUE(decode_class_description(bytes, back, error)) << error;
  EXPECT_EQ(back, d);
  EXPECT_EQ(back.find_command("RESET")->body->fields.at(0).name, "start");
  EXPECT_TRUE(std::isinf(back.find_parameter("step")->max));
  EXPECT_EQ(back.find_parameter("step")->unit, "1/s");
  const auto table = back.data->field_table();
  ASSERT_EQ(table.size(), 3u);
  EXPECT_STREQ(table[2].name, "label");
  EXPECT_EQ(table[2].count, 8u);
}

TEST(ClassDescriptionTest, EveryTruncationIsRefusedWithItsOffset) {
  const std::vector<std::byte> bytes = encode_class_description(sample_description());
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    ClassDescription out;
    std::string error;
    EXPECT_FALSE(decode_class_description(std::span<const std::byte>(bytes).first(n), out, error)) << n;
    EXPECT_EQ(error.rfind("byte ", 0), 0u) << error;
  }
  std::vector<std::byte> longer = bytes;
  longer.push_back(std::byte{0});
  ClassDescription out;
  std::string error;
  // Bytes after the parameters are the optional value-names section: one byte is not.
  EXPECT_FALSE(decode_class_description(longer, out, error));
  EXPECT_NE(error.find("value names: ends inside"), std::string::npos) << error;
  // An empty section is refused too (the encoder leaves it out): one encoding each.
  longer.push_back(std::byte{0});
  EXPECT_FALSE(decode_class_description(longer, out, error));
  EXPECT_NE(error.find("names no field"), std::string::npos) << error;
}

// Finds `text` (a length-prefixed string of the encoding) and returns the offset of its bytes.
std::size_t find_text(const std::vector<std::byte>& bytes, const std::string& text) {
  for (std::size_t i = 0; i + text.size() <= bytes.size(); ++i) {
    if (std::memcmp(bytes.data() + i, text.data(), text.size()) == 0) return i;
  }
  ADD_FAILURE() << "no '" << text << "' in the encoding";
  return 0;
}

TEST(ClassDescriptionTest, RefusesWhatToolsMustNotTrust) {
  const std::vector<std::byte> good = encode_class_description(sample_description());
  auto refused = [&](std::vector<std::byte> bytes, const std::string& expected) {
    ClassDescription out;
    std::string error;
    EXPECT_FALSE(decode_class_description(bytes, out, error)) << expected;
    EXPECT_NE(error.find(expected), std::string::npos) << error;
  };
  {  // A control character in a doc (an escape sequence for the terminal).
    auto b = good;
    b[find_text(b, "direction")] = std::byte{0x1B};
    refused(b, "parameter 1 'mode': parameter doc has a control character");
  }
  {  // A field name that is not a name.
    auto b = good;
    b[find_text(b, "rate")] = std::byte{' '};
    refused(b, "field name is not a name");
  }
  {  // A field past its type: label's count 8 -> 9 (offset 16 + 9 > 24).
    auto b = good;
    const std::size_t at = find_text(b, "label") + 5 + 1 + 4;  // name, kind, offset
    b[at] = std::byte{9};
    refused(b, "does not lie inside its 24 bytes");
  }
  {  // An unknown field kind.
    auto b = good;
    b[find_text(b, "label") + 5] = std::byte{200};
    refused(b, "unknown kind 200");
  }
  {  // A command type that is a generic message.
    auto b = good;
    b[find_text(b, "FREEZE") + 6] = std::byte{4};
    refused(b, "type 4 is not a class command");
  }
  {  // Another version.
    auto b = good;
    b[4] = std::byte{2};
    refused(b, "version 2");
  }
  {  // Not a description at all.
    auto b = good;
    b[0] = std::byte{'X'};
    refused(b, "not a class description");
  }
  {  // A string length beyond the limit.
    auto b = good;
    const std::size_t at = find_text(b, "Counter") - 2;
    b[at] = std::byte{0xFF};
    b[at + 1] = std::byte{0xFF};
    refused(b, "at most 64");
  }
}

TEST(ClassDescriptionTest, EncoderRefusesWhatTheDecoderWould) {
  ClassDescription d = sample_description();
  d.parameters[0].doc = "bell\a";
  EXPECT_THROW((void)encode_class_description(d), std::invalid_argument);
  d = sample_description();
  d.data->fields[2].count = 9;
  EXPECT_THROW((void)encode_class_description(d), std::invalid_argument);
  d = sample_description();
  d.commands[0].name = "two words";
  EXPECT_THROW((void)encode_class_description(d), std::invalid_argument);
}

TEST(ClassDescriptionTest, PagesAssembleAndRefuseAnotherPage) {
  ClassDescription d = sample_description();
  for (int i = 0; i < 60; ++i) {  // about 20 KB: three pages
    ParameterDescription p = d.parameters[0];
    p.name = std::to_string(i);
    p.name.insert(0, 1, 'p');
    p.doc = std::string(300, 'd');
    d.parameters.push_back(p);
  }
  const std::vector<std::byte> bytes = encode_class_description(d);
  ASSERT_GT(bytes.size(), 2 * kClassPageBytes);
  ClassPageAssembler assembler;
  int pages = 0;
  while (!assembler.complete()) {
    ClassPageRequest q;
    q.offset = assembler.next_offset();
    ClassPageHeader h;
    std::span<const std::byte> page;
    ASSERT_EQ(class_page(bytes, bytes.size(), bytes_of(q), true, h, page), nullptr);
    std::vector<std::byte> body(sizeof h + page.size());
    std::memcpy(body.data(), &h, sizeof h);
    std::memcpy(body.data() + sizeof h, page.data(), page.size());
    std::string error;
    ASSERT_TRUE(assembler.add(body, true, error)) << error;
    ASSERT_LT(++pages, 10);
  }
  EXPECT_EQ(pages, 3);
  ClassDescription back;
  std::string error;
  ASSERT_TRUE(decode_class_description(assembler.bytes(), back, error)) << error;
  EXPECT_EQ(back, d);

  // A page at another offset, a changed total, an offset past the end.
  ClassPageAssembler a2;
  ClassPageHeader h{static_cast<uint32_t>(bytes.size()), 8192};
  std::vector<std::byte> body(sizeof h + kClassPageBytes);
  std::memcpy(body.data(), &h, sizeof h);
  EXPECT_FALSE(a2.add(body, true, error));
  EXPECT_NE(error.find("offset 8192, 0 asked"), std::string::npos) << error;
  ClassPageRequest past;
  past.offset = static_cast<uint32_t>(bytes.size());
  std::span<const std::byte> page;
  EXPECT_NE(class_page(bytes, bytes.size(), bytes_of(past), true, h, page), nullptr);
}

// The value names of enum and address fields (an optional section after the
// parameters): served only to a client that asks for them, so that a client that
// predates them gets the bytes it always got; checked on both sides.
TEST(ClassDescriptionTest, ValueNamesAreServedToClientsThatAskForThem) {
  ClassDescription d = sample_description();
  d.data->size = 32;
  d.data->fields.push_back({"state", tims::FieldKind::kU8, 24, 1, ""});
  d.data->fields.push_back({"owner", tims::FieldKind::kU32, 28, 1, ""});
  d.value_names = {{"state", false, {{0, "IDLE"}, {1, "RUNNING"}, {7, "2D"}}}, {"owner", true, {}}};
  std::size_t base = 0;
  const std::vector<std::byte> bytes = encode_class_description(d, &base);
  ASSERT_LT(base, bytes.size());
  ClassDescription back;
  std::string error;
  ASSERT_TRUE(decode_class_description(bytes, back, error)) << error;
  EXPECT_EQ(back, d);
  ASSERT_NE(back.value_names[0].name_of(7), nullptr);
  EXPECT_STREQ(back.value_names[0].name_of(7), "2D");
  EXPECT_EQ(back.value_names[0].name_of(2), nullptr);
  // Without the section: the description as before, without names.
  ASSERT_TRUE(decode_class_description(std::span(bytes).first(base), back, error)) << error;
  EXPECT_TRUE(back.value_names.empty());
  ClassDescription plain = d;
  plain.value_names.clear();
  EXPECT_EQ(back, plain);
  std::size_t plain_base = 0;
  EXPECT_EQ(encode_class_description(plain, &plain_base).size(), base);
  EXPECT_EQ(plain_base, base);

  // The server: `total` is the base unless the request asks for the section.
  ClassPageRequest q;
  ClassPageHeader h;
  std::span<const std::byte> page;
  ASSERT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
  EXPECT_EQ(h.total, base);
  EXPECT_EQ(page.size(), base);
  ASSERT_EQ(class_page(bytes, base, {}, true, h, page), nullptr);  // an empty body: offset 0, no sections
  EXPECT_EQ(h.total, base);
  q.sections = kClassSectionValueNames;
  ASSERT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
  EXPECT_EQ(h.total, bytes.size());
  q.offset = static_cast<uint32_t>(base);  // inside the section: only for a client that asks
  EXPECT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
  q.sections = 0;
  EXPECT_NE(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);

  // Cut inside the section, a byte after it (where the field units would start):
  // refused with the place.
  EXPECT_FALSE(decode_class_description(std::span(bytes).first(bytes.size() - 1), back, error));
  EXPECT_NE(error.find("value names 1 'owner'"), std::string::npos) << error;
  std::vector<std::byte> longer = bytes;
  longer.push_back(std::byte{0});
  EXPECT_FALSE(decode_class_description(longer, back, error));
  EXPECT_NE(error.find("field units: ends inside"), std::string::npos) << error;

  // What cannot name values: refused by the encoder (the decoder applies the same rules).
  const auto refused = [&](std::vector<FieldNamesDescription> names, const std::string& why) {
    ClassDescription bad = d;
    bad.value_names = std::move(names);
    try {
      (void)encode_class_description(bad);
      ADD_FAILURE() << "encoded: " << why;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  refused({{"speed", false, {{0, "A"}}}}, "has no such field");
  refused({{"rate", false, {{0, "A"}}}}, "not an integer of at most 4 bytes");
  refused({{"count", false, {{0, "A"}}}}, "not an integer of at most 4 bytes");
  refused({{"state", false, {{0, "A"}, {0, "B"}}}}, "value 0 named twice");
  refused({{"state", false, {{0, "A"}, {1, "A"}}}}, "name 'A' given twice");
  refused({{"state", false, {}}}, "no values");
  refused({{"state", true, {}}}, "an address field is a u32");
  refused({{"state", false, {{0, "A"}}}, {"state", false, {{1, "B"}}}}, "named twice");
  refused({{"state", false, {{0, "A\x1b"}}}}, "printable");
  ClassDescription no_data = sample_description();
  no_data.data.reset();
  no_data.value_names = {{"state", false, {{0, "A"}}}};
  EXPECT_THROW((void)encode_class_description(no_data), std::invalid_argument);
}

// The units of the data fields (an optional section after the value names): served
// only to a client that asks for them, with the value names; a client that asks only
// for names, or none, gets the bytes it got before units.
TEST(ClassDescriptionTest, FieldUnitsAreServedToClientsThatAskForThem) {
  ClassDescription d = sample_description();
  d.data->fields[1].unit = "1/s";
  d.data->fields[0].unit = "m";
  std::size_t base = 0;
  const std::vector<std::byte> bytes = encode_class_description(d, &base);
  ClassDescription back;
  std::string error;
  ASSERT_TRUE(decode_class_description(bytes, back, error)) << error;
  EXPECT_EQ(back, d);
  EXPECT_EQ(back.data->fields[1].unit, "1/s");
  EXPECT_TRUE(back.value_names.empty());
  // Without units: what a description without them encodes to, cut at the base.
  ClassDescription plain = d;
  for (auto& f : plain.data->fields) f.unit.clear();
  EXPECT_EQ(encode_class_description(plain).size(), base);
  ASSERT_TRUE(decode_class_description(std::span(bytes).first(base), back, error)) << error;
  EXPECT_EQ(back, plain);

  // The server: none, names only (the class names no values: the base), or all.
  ClassPageRequest q;
  ClassPageHeader h;
  std::span<const std::byte> page;
  ASSERT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
  EXPECT_EQ(h.total, base);
  q.sections = kClassSectionValueNames;
  ASSERT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
  EXPECT_EQ(h.total, base);
  q.sections = kClassSectionFieldUnits;
  ASSERT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
  EXPECT_EQ(h.total, bytes.size());

  // With value names too: names-only clients get the names and no units.
  ClassDescription named = d;
  named.data->size = 32;
  named.data->fields.push_back({"state", tims::FieldKind::kU8, 24, 1, "s"});  // a unit on an enum: allowed
  named.value_names = {{"state", false, {{0, "IDLE"}, {1, "RUNNING"}}}};
  const std::vector<std::byte> all = encode_class_description(named, &base);
  ASSERT_TRUE(decode_class_description(all, back, error)) << error;
  EXPECT_EQ(back, named);
  q.sections = kClassSectionValueNames;
  ASSERT_EQ(class_page(all, base, bytes_of(q), true, h, page), nullptr);
  ASSERT_LT(h.total, all.size());
  ClassDescription names_only;
  ASSERT_TRUE(decode_class_description(std::span(all).first(h.total), names_only, error)) << error;
  EXPECT_EQ(names_only.value_names, named.value_names);
  for (const auto& f : names_only.data->fields) EXPECT_TRUE(f.unit.empty()) << f.name;
  q.sections = kClassSectionValueNames | kClassSectionFieldUnits;
  ASSERT_EQ(class_page(all, base, bytes_of(q), true, h, page), nullptr);
  EXPECT_EQ(h.total, all.size());

  // Malformed sections: refused with the place.
  // At the base: the names section, empty (u16 0); then the units: u16 2, {u16 0, "m"}, {u16 1, "1/s"}.
  std::size_t base_again = 0;
  (void)encode_class_description(d, &base_again);
  const std::size_t units_at = base_again;
  ASSERT_EQ(bytes.size(), units_at + 2 + 2 + (2 + 2 + 1) + (2 + 2 + 3));
  auto patched = [&](std::size_t at, std::initializer_list<uint8_t> with) {
    std::vector<std::byte> b = bytes;
    std::size_t i = at;
    for (const uint8_t v : with) b[i++] = std::byte{v};
    return b;
  };
  const auto refused = [&](const std::vector<std::byte>& b, const std::string& why) {
    ClassDescription out;
    std::string e;
    EXPECT_FALSE(decode_class_description(b, out, e)) << why;
    EXPECT_NE(e.find(why), std::string::npos) << e;
  };
  ASSERT_EQ(std::to_integer<int>(bytes[units_at]) | std::to_integer<int>(bytes[units_at + 1]), 0);  // no names
  ASSERT_EQ(std::to_integer<int>(bytes[units_at + 2]), 2);                                          // two units
  EXPECT_EQ(std::to_integer<int>(bytes[units_at + 4]), 0);  // the first: field 0
  refused(patched(units_at + 4, {1, 0}), "field index 1 is not a field of 'CounterData' after the previous one");
  refused(patched(units_at + 4, {9, 0}), "field index 9 is not a field");
  refused(patched(units_at + 6, {0, 0}), "field 'count' has an empty unit");
  std::vector<std::byte> cut = bytes;
  cut.resize(units_at + 4);  // the names section's empty count, a units count, no units
  refused(cut, "field units 0: ends inside field index");
  cut.resize(units_at + 2);  // an empty names section and nothing after it
  refused(cut, "names no field");
  std::vector<std::byte> no_units = bytes;
  no_units.resize(units_at + 4);
  no_units[units_at + 2] = std::byte{0};
  no_units[units_at + 3] = std::byte{0};
  refused(no_units, "gives no unit");
  std::vector<std::byte> longer = bytes;
  longer.push_back(std::byte{0});
  refused(longer, "bytes after the end");

  // What the encoder refuses: units on a command's body (data types only).
  ClassDescription body_unit = d;
  body_unit.commands[0].body->fields[0].unit = "m";
  EXPECT_THROW((void)encode_class_description(body_unit), std::invalid_argument);
}

// A running component answers GET_CLASS with its class's description.
TEST(ClassDescriptionTest, ComponentAnswersGetClass) {
  test::HostUnderTest host(R"(
system: 0
lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
)");
  const tims::Address gen = host.address_of("gen");
  ClassPageAssembler assembler;
  while (!assembler.complete()) {
    ClassPageRequest q;
    q.offset = assembler.next_offset();
    const auto r = host.call_with(gen, tims::msg::kGetClass, q);
    ASSERT_EQ(r.status, tims::CallStatus::kOk);
    ASSERT_EQ(r.type, tims::msg::kClass) << r.error_text();
    std::string error;
    ASSERT_TRUE(assembler.add(std::span(reinterpret_cast<const std::byte*>(r.body.data()), r.body.size()), true, error))
        << error;
  }
  ClassDescription d;
  std::string error;
  ASSERT_TRUE(decode_class_description(assembler.bytes(), d, error)) << error;
  EXPECT_EQ(d.impl, "Generator");
  EXPECT_EQ(d.class_name, "Generator");
  EXPECT_EQ(d.class_id, class_ids::kGenerator);
  ASSERT_TRUE(d.data.has_value());
  EXPECT_NE(d.find_parameter(Component::kLogLevelParam), nullptr);
  ASSERT_NE(d.find_parameter("frequency_hz"), nullptr);
  EXPECT_EQ(d.find_parameter("frequency_hz")->unit, "Hz");
  EXPECT_EQ(d.find_parameter("frequency_hz")->default_value, "0.5");

  // A malformed request is refused with its reason, an offset past the end too.
  const auto bad = host.call(gen, tims::msg::kGetClass, "abc", 3);
  EXPECT_EQ(bad.type, tims::msg::kError);
  EXPECT_NE(bad.error_text().find("GET_CLASS"), std::string::npos);
  ClassPageRequest past;
  past.offset = 1u << 30;
  EXPECT_EQ(host.call_with(gen, tims::msg::kGetClass, past).type, tims::msg::kError);
}

// Issue 19's test of item 3: a class is described as it is declared, its description
// survives the GET_CLASS paging and the decoder, and its data size is the payload its
// component publishes.
void expect_described_as_declared(const ComponentClass* cls) {
  const std::unique_ptr<Component> c = cls->make();
  const ClassDescription d = describe_class(*cls, c->parameters());
  std::vector<std::byte> bytes;
  std::size_t base = 0;
  ASSERT_NO_THROW(bytes = encode_class_description(d, &base));
  // Through the pages the command task serves, with the value names.
  ClassPageAssembler assembler;
  while (!assembler.complete()) {
    ClassPageRequest q;
    q.offset = assembler.next_offset();
    q.sections = kClassSectionValueNames | kClassSectionFieldUnits;
    ClassPageHeader h;
    std::span<const std::byte> page;
    ASSERT_EQ(class_page(bytes, base, bytes_of(q), true, h, page), nullptr);
    std::vector<std::byte> body(sizeof h + page.size());
    std::memcpy(body.data(), &h, sizeof h);
    std::memcpy(body.data() + sizeof h, page.data(), page.size());
    std::string error;
    ASSERT_TRUE(assembler.add(body, true, error)) << error;
  }
  ClassDescription back;
  std::string error;
  ASSERT_TRUE(decode_class_description(assembler.bytes(), back, error)) << error;
  EXPECT_EQ(back, d);

  // As declared.
  EXPECT_EQ(back.impl, cls->impl);
  EXPECT_EQ(back.class_id, cls->class_id);
  EXPECT_EQ(back.summary, cls->description);
  // The names of its enum values and address fields, as its data type declares them.
  const std::size_t declared_names = cls->data != nullptr ? cls->data->value_names.size() : 0;
  ASSERT_EQ(back.value_names.size(), declared_names);
  for (std::size_t i = 0; i < declared_names; ++i) {
    EXPECT_EQ(back.value_names[i].field, cls->data->value_names[i].field);
    EXPECT_EQ(back.value_names[i].values.size(), cls->data->value_names[i].values.size());
  }
  // The units of its data fields, as declared.
  std::size_t units = 0;
  if (back.data) {
    for (const auto& f : back.data->fields) {
      if (!f.unit.empty()) ++units;
    }
  }
  EXPECT_EQ(units, cls->data != nullptr ? cls->data->units.size() : 0);
  if (cls->data != nullptr) {
    for (const FieldUnit& u : cls->data->units) {
      bool found = false;
      for (const auto& f : back.data->fields) found = found || (f.name == u.field && f.unit == u.unit);
      EXPECT_TRUE(found) << u.field << " (" << u.unit << ")";
    }
  }
  ASSERT_EQ(back.parameters.size(), c->parameters().size());
  for (std::size_t i = 0; i < back.parameters.size(); ++i) {
    EXPECT_EQ(back.parameters[i].name, c->parameters().at(i).name());
    EXPECT_EQ(back.parameters[i].doc, c->parameters().at(i).spec().doc);
    EXPECT_EQ(back.parameters[i].kind, c->parameters().at(i).kind());
  }
  ASSERT_EQ(back.commands.size(), cls->commands.size());
  for (std::size_t i = 0; i < back.commands.size(); ++i) {
    EXPECT_EQ(back.commands[i].name, cls->commands[i].name);
    EXPECT_EQ(back.commands[i].type, cls->commands[i].type);
    ASSERT_EQ(back.commands[i].body.has_value(), cls->commands[i].body != nullptr);
    if (back.commands[i].body) {
      EXPECT_EQ(back.commands[i].body->size, cls->commands[i].body->size);
    }
  }

  // The data type is what the component publishes: its sample size and field table.
  const auto* producer = dynamic_cast<const DataComponentBase*>(c.get());
  if (producer == nullptr) {
    EXPECT_FALSE(back.data.has_value()) << "describes data but publishes none";
    return;
  }
  ASSERT_TRUE(back.data.has_value()) << "publishes " << producer->payload_size() << "-byte samples, describes none";
  EXPECT_EQ(back.data->size, producer->payload_size());
  const auto fields = producer->payload_fields();
  ASSERT_EQ(back.data->fields.size(), fields.size());
  for (std::size_t i = 0; i < fields.size(); ++i) {
    EXPECT_EQ(back.data->fields[i].name, fields[i].name);
    EXPECT_EQ(back.data->fields[i].kind, fields[i].kind);
    EXPECT_EQ(back.data->fields[i].offset, fields[i].offset);
    EXPECT_EQ(back.data->fields[i].count, fields[i].count);
  }
}

TEST(ClassDescriptionTest, EveryBuiltinClassIsDescribedAsDeclared) {
  ComponentRegistry registry;
  components::register_builtin(registry);
  const auto classes = registry.all();
  ASSERT_GE(classes.size(), 20u);
  for (const ComponentClass* cls : classes) {
    SCOPED_TRACE(cls->impl);
    expect_described_as_declared(cls);
  }
}

// The same for every plug-in class of the tree (MCL, Scan3D, Camera, the replays ...),
// loaded by name from the build tree's plug-in folder as rackd loads them (this program
// lies in the build tree: ComponentRegistry::plugin_dirs()).
TEST(ClassDescriptionTest, EveryPluginClassOfTheTreeIsDescribedAsDeclared) {
  ComponentRegistry registry;
  const std::vector<PluginClassInfo> plugins = registry.plugin_classes();
  std::vector<std::string> names;
  for (const PluginClassInfo& p : plugins) names.push_back(p.impl);
  for (const char* expected : {"MCL", "Scan3D", "ChassisReplay", "LadarReplay"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end())
        << expected << " is not among the build tree's plug-in classes";
  }
  for (const PluginClassInfo& p : plugins) {
    SCOPED_TRACE(p.impl);
    std::string error;
    const ComponentClass* cls = registry.resolve(p.impl, error);
    ASSERT_NE(cls, nullptr) << error;
    expect_described_as_declared(cls);
  }
}

}  // namespace
}  // namespace rack
