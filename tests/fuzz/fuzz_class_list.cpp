// libFuzzer harness for rackctl's reading of `rackd --list-classes --json`
// (tools/rackctl/class_info.cpp: parse_class_list), the output of a child process
// that rackctl graph/alloc and rack-gui's configuration view take the classes'
// component references from. The rackd run may be another version, a broken build
// or any program named by --rackd: its output is outside input.
//
// Input: the whole of the child's standard output. Properties: parse_class_list never
// throws; a refusal says why; an accepted list has a class for every element of the
// JSON array, each with its implementation name, a class id of 1..255 or -1, and
// component references only where the class is described.
//
// Seeds: tests/fuzz/corpus/class_list/ (a built-in class described in full, a plug-in
// known by its manifest only, an empty list).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "class_info.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<rack::deploy::ClassInfo> classes;
  std::string why;
  bool ok = false;
  try {
    ok = rack::tools::parse_class_list(text, classes, why);
  } catch (...) {
    rack::fuzz::check_failed("parse_class_list threw", __FILE__, __LINE__);
  }
  if (!ok) {
    FUZZ_CHECK(!why.empty());
    return 0;
  }
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  FUZZ_CHECK(j.is_array() && j.size() == classes.size());
  for (const rack::deploy::ClassInfo& c : classes) {
    FUZZ_CHECK(c.class_id == -1 || (c.class_id >= 1 && c.class_id <= 255));
    FUZZ_CHECK(c.described || c.refs.empty());
  }
  return 0;
}
