// libFuzzer harness: PGM map images (rack::maps::parse_pgm, the bytes load_map reads).
// Invariant checked beyond "no crash, no leak, no UB": a decoded image holds exactly
// width x height pixels, none above maxval, and errors name the file and a byte.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   components/maps/src/occupancy_map.cpp core/rt/src/input_file.cpp; -Icomponents/maps/include -Icore/rt/include; -lyaml-cpp.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "rack/maps/occupancy_map.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  std::vector<rack::maps::MapError> errors;
  const auto img = rack::maps::parse_pgm("fuzz.pgm", bytes, errors);
  if (img) {
    if (!errors.empty()) std::abort();
    if (img->pixels.size() != static_cast<std::size_t>(img->width) * static_cast<std::size_t>(img->height))
      std::abort();
    for (uint8_t p : img->pixels) {
      if (p > img->maxval) std::abort();
    }
  } else {
    if (errors.empty() || errors[0].file != "fuzz.pgm" || errors[0].byte_offset < 0) std::abort();
    if (static_cast<std::size_t>(errors[0].byte_offset) > size) std::abort();
  }
  return 0;
}
