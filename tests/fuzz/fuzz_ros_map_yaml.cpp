// libFuzzer harness: ROS map_server YAML files (rack::maps::parse_map_yaml, the text
// load_map reads before it opens the image). Invariant: either a complete MapYaml with
// values load_map accepts, or at least one error naming the file.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   components/maps/src/occupancy_map.cpp core/rt/src/input_file.cpp; -Icomponents/maps/include -Icore/rt/include; -lyaml-cpp.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "rack/maps/occupancy_map.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<rack::maps::MapError> errors;
  const auto y = rack::maps::parse_map_yaml("fuzz.yaml", text, errors);
  if (y) {
    if (!errors.empty() || y->image.empty() || !(y->resolution > 0.0)) std::abort();
    if (!(y->free_thresh <= y->occupied_thresh)) std::abort();
    for (double v : y->origin) {
      if (!std::isfinite(v)) std::abort();
    }
  } else if (errors.empty() || errors[0].file != "fuzz.yaml") {
    std::abort();
  }
  return 0;
}
