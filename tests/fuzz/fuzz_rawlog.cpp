// libFuzzer harness: MRPT rawlogs (rack::replay::parse_rawlog: our bounded gunzip, then
// MRPT's own deserialisation of each record, caught at the boundary). Invariant: no
// exception escapes, every error names the file, and an empty result has an error.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "rawlog_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  const rack::replay::LoadLogResult r = rack::replay::parse_rawlog("fuzz.rawlog", bytes);
  for (const auto& e : r.errors) {
    if (e.file != "fuzz.rawlog") std::abort();
  }
  if (r.log.scans.empty() && r.errors.empty()) std::abort();
  for (const auto& s : r.log.scans) {
    if (s.ranges.size() < 2) std::abort();
  }
  return 0;
}
