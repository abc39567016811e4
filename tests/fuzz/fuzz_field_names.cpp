// libFuzzer harness for rackctl's names of enum and address fields
// (tools/rackctl/field_names.h: field_names_json), which reads sample bytes a component
// sent over the network. Byte 0 is the TiMS class id, byte 1 bit 0 the byte order; the
// rest is the sample, laid out by the class's field table, named by the value names
// its data type declares (as its description carries them). The answer must be empty or
// one valid JSON object of strings; never a crash or a read past the sample.
//
// Seeds: tests/fuzz/corpus/field_names/ (a Pilot, a Chassis and a GPS sample, each also
// one byte short).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "field_names.h"
#include "rack/components/class_declarations.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const uint8_t class_id = data[0];
  const bool native = (data[1] & 1u) == 0;
  const std::span<const std::byte> sample(reinterpret_cast<const std::byte*>(data + 2), size - 2);
  const rack::DataTypeInfo* type = nullptr;  // the class's declared data type
  for (const rack::components::ClassDeclaration& d : rack::components::class_declarations()) {
    if (d.class_id == class_id && d.data != nullptr) type = d.data;
  }
  if (type == nullptr) return 0;
  // The value names as the class's description carries them (GET_CLASS).
  std::vector<rack::FieldNamesDescription> names;
  for (const rack::FieldValueNames& n : type->value_names) {
    rack::FieldNamesDescription d{n.field, n.address, {}};
    for (const rack::ValueName& v : n.values) d.values.push_back({v.value, v.name});
    names.push_back(std::move(d));
  }
  const std::string j = rack::tools::field_names_json(names, type->fields, sample, native);
  if (j.empty()) return 0;
  const auto parsed = nlohmann::json::parse(j, nullptr, false);
  if (parsed.is_discarded() || !parsed.is_object()) __builtin_trap();
  for (const auto& [k, v] : parsed.items()) {
    if (!v.is_string()) __builtin_trap();
  }
  return 0;
}
