// libFuzzer harness: CARMEN logs (rack::replay::parse_carmen_text, the text
// load_carmen_log reads). Invariants: every error names the file and (for a line) a
// line within the text; scans carry finite ranges only; the kept error list
// stays within its limit.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   components/replay/src/carmen_log.cpp core/rt/src/input_file.cpp; -Icomponents/replay/include -Icore/rt/include.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "rack/replay/carmen_log.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const rack::replay::LoadLogResult r = rack::replay::parse_carmen_text(text, "fuzz.log");
  if (r.errors.size() > rack::replay::kMaxLogErrors) std::abort();
  for (const auto& e : r.errors) {
    if (e.file != "fuzz.log" || e.line < 0 || static_cast<uint64_t>(e.line) > r.lines) std::abort();
  }
  for (const auto& s : r.log.scans) {
    for (float v : s.ranges) {
      if (!std::isfinite(v)) std::abort();
    }
  }
  (void)r.error_text();
  return 0;
}
