// The class description a tool receives (rack/core/class_description.h): GET_CLASS
// reply pages assembled and the description decoded, as rackctl, gdos and rack-gui do.
//
// Input: byte 0 picks the mode, the rest is the data. Modes:
//   even  one encoded description: decode_class_description(); when it is accepted,
//         encoding it again gives the same bytes (the encoding is canonical), every
//         field lies inside its type, and its field tables print as valid JSON
//         through payload_to_json (zero bodies of the declared size, at most 4 KiB);
//         the prefixes served without the optional sections (value names, field
//         units) and with the names only decode to it without those parts;
//   odd   CLASS reply bodies: each is a 2-byte length (little-endian) and that many bytes (byte order
//         from the mode's bit 1), fed to ClassPageAssembler until one is refused or
//         the description is complete, which is then decoded as above; also
//         class_page() (the server's side) over the data with each body as a request
//         (the mode's upper bits choose the length served without optional sections).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "fuzz_support.h"
#include "rack/core/class_description.h"
#include "rack/core/payload_json.h"

namespace {

using rack::fuzz::FuzzInput;

void check_type(const rack::TypeDescription& t) {
  for (const auto& f : t.fields) {
    FUZZ_CHECK(f.count > 0);
    FUZZ_CHECK(uint64_t{f.offset} + uint64_t{f.count} * rack::tims::field_kind_size(f.kind) <= t.size);
  }
  const std::vector<std::byte> body(std::min<std::size_t>(t.size, 4096));
  const auto table = t.field_table();
  FUZZ_CHECK(nlohmann::json::accept(rack::payload_to_json(table, body, true)));
}

void decode(std::span<const std::byte> bytes) {
  rack::ClassDescription d;
  std::string error;
  if (!rack::decode_class_description(bytes, d, error)) {
    FUZZ_CHECK(!error.empty());
    return;
  }
  std::size_t base = 0;
  const std::vector<std::byte> again = rack::encode_class_description(d, &base);
  FUZZ_CHECK(again.size() == bytes.size() && std::equal(again.begin(), again.end(), bytes.begin()));
  bool units = false;
  if (d.data) {
    for (const auto& f : d.data->fields) units = units || !f.unit.empty();
  }
  // Without its optional sections (what a client that does not ask is served) it
  // decodes to the same description without value names and units; served to a
  // client that asks only for names, with the names and without units.
  FUZZ_CHECK(base <= bytes.size() && (base == bytes.size()) == (d.value_names.empty() && !units));
  if (base < bytes.size()) {
    rack::ClassPageRequest q;
    q.sections = rack::kClassSectionValueNames;
    rack::ClassPageHeader h;
    std::span<const std::byte> page;
    FUZZ_CHECK(rack::class_page(bytes, base, std::span(reinterpret_cast<const std::byte*>(&q), sizeof q), true, h,
                                page) == nullptr);
    FUZZ_CHECK(h.total >= base && h.total <= bytes.size());
    rack::ClassDescription named;
    FUZZ_CHECK(rack::decode_class_description(bytes.first(h.total), named, error));
    rack::ClassPageRequest none;
    FUZZ_CHECK(rack::class_page(bytes, base, std::span(reinterpret_cast<const std::byte*>(&none), sizeof none), true, h,
                                page) == nullptr &&
               h.total == base);
    rack::ClassDescription plain;
    FUZZ_CHECK(rack::decode_class_description(bytes.first(base), plain, error));
    rack::ClassDescription expect = d;
    if (expect.data) {
      for (auto& f : expect.data->fields) f.unit.clear();
    }
    FUZZ_CHECK(named == expect);
    expect.value_names.clear();
    FUZZ_CHECK(plain == expect);
  }
  if (d.data) check_type(*d.data);
  for (const auto& c : d.commands) {
    FUZZ_CHECK(c.type >= 21);
    if (c.body) check_type(*c.body);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  const uint8_t mode = in.byte();
  if ((mode & 1) == 0) {
    const auto rest = in.rest();
    decode(std::span(reinterpret_cast<const std::byte*>(rest.data()), rest.size()));
    return 0;
  }
  const bool native = (mode & 2) == 0;
  rack::ClassPageAssembler assembler;
  std::vector<std::span<const uint8_t>> bodies;
  while (!in.empty()) bodies.push_back(in.bytes(in.take<uint16_t>()));
  for (const auto b : bodies) {
    std::string error;
    if (!assembler.add(std::span(reinterpret_cast<const std::byte*>(b.data()), b.size()), native, error)) break;
    if (assembler.complete()) {
      decode(assembler.bytes());
      break;
    }
  }
  const std::span<const std::byte> whole(reinterpret_cast<const std::byte*>(data), size);
  for (const auto b : bodies) {
    rack::ClassPageHeader h;
    std::span<const std::byte> page;
    // The base (the description without its optional sections) from the mode's
    // upper bits: all of it, or a prefix.
    const std::size_t base = (mode >> 2) == 0 ? size : std::min<std::size_t>(size, (mode >> 2) * 16u);
    if (rack::class_page(whole, base, std::span(reinterpret_cast<const std::byte*>(b.data()), b.size()), native, h,
                         page) == nullptr) {
      FUZZ_CHECK(h.total >= std::min(base, size) && h.total <= size && h.offset < h.total &&
                 page.size() <= rack::kClassPageBytes);
      FUZZ_CHECK(page.data() == whole.data() + h.offset && h.offset + page.size() <= h.total);
    }
  }
  return 0;
}
