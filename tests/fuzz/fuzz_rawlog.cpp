// libFuzzer harness: MRPT rawlogs (rack::replay::parse_rawlog: our bounded gunzip, then
// MRPT's own deserialisation of each record, caught at the boundary). Invariant: no
// exception escapes, every error names the file, and an empty result has an error.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   components/replay/src/rawlog_reader.cpp components/replay/src/carmen_log.cpp core/rt/src/input_file.cpp;
//   -Icomponents/replay/include -Icomponents/replay/src -Icore/rt/include, MRPT's include dirs
//   (-isystem /usr/include/mrpt/<module>/include for obs poses serialization io rtti core typemeta
//   math system containers config img opengl bayes random expr tfest, and /usr/include/eigen3);
//   -lmrpt-obs -lmrpt-poses -lmrpt-io -lmrpt-serialization -lmrpt-rtti -lmrpt-core -lmrpt-system
//   -lmrpt-math -lz. MRPT itself crashes and over-allocates on corrupt data (rackd isolates it in a
//   child process, load_rawlog): run with -fork=1 -ignore_crashes=1 -ignore_ooms=1 to go past them.
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
