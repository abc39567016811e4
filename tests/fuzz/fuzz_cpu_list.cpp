// libFuzzer harness for kernel CPU lists (core/rt/src/capabilities.cpp: parse_cpu_list),
// read from /sys/devices/system/cpu/online by rackd at start (probe_capabilities; a
// container may bind anything there).
//
// Input: the file's text. Properties: never throws, ends and stays within memory; an
// accepted list is not empty and holds CPU numbers below 8192 (the kernel's NR_CPUS is
// at most 8192).
//
// Seeds: tests/fuzz/corpus/cpu_list/ (a single CPU, ranges and singles, 0-63).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "rack/rt/capabilities.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<int> cpus;
  bool ok = false;
  try {
    ok = rack::rt::parse_cpu_list(text, cpus);
  } catch (...) {
    rack::fuzz::check_failed("parse_cpu_list threw", __FILE__, __LINE__);
  }
  if (!ok) return 0;
  FUZZ_CHECK(!cpus.empty());
  for (const int c : cpus) FUZZ_CHECK(c >= 0 && c < 8192);
  return 0;
}
