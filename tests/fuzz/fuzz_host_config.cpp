// libFuzzer harness for the host-file loader (rack/core/host_config.h), a decoder of
// outside input: any bytes go to load_host_text(), as rackd --check would read them
// from a file. The loader must never crash, hang, throw or allocate without bound,
// and must answer either a host or at least one error naming the file.
//
// Plug-ins and key files named by the input are not opened (HostLoadOptions::
// open_files = false): a fuzzer must not dlopen or read paths of its own choosing.
// The component classes are the built-in ones, so each class's parameter checks
// (Component::check_parameters) are fuzzed too.
//
// Seeds: tests/fuzz/corpus/host_config/ (small copies of configs/*.yaml).
//
// By hand (until tests/fuzz/CMakeLists.txt builds it): the loader and the parameter
// code compiled with clang and the sanitizers, the rest linked from a normal build
// (build/, its libraries and their link line as rack_unit_tests has it):
//   clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer-no-link,address,undefined -I... -c
//       tests/fuzz/fuzz_host_config.cpp core/src/host_config*.cpp core/src/parameters.cpp
//     tims/src/lcm_url.cpp components/pilot/pilot.cpp components/path/path.cpp
//   clang++-14 -fsanitize=fuzzer,address,undefined *.o <rack_unit_tests' libraries> -o fuzz_host_config
//   ./fuzz_host_config -max_total_time=600 -max_len=8192 CORPUS_DIR tests/fuzz/corpus/host_config
#include <cstddef>
#include <cstdint>
#include <string>

#include "rack/components/builtin.h"
#include "rack/core/host_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static rack::ComponentRegistry* registry = [] {
    auto* r = new rack::ComponentRegistry;  // lives for the process (classes are registered once)
    rack::components::register_builtin(*r);
    return r;
  }();
  static const rack::rt::RtCapabilities caps = [] {
    rack::rt::RtCapabilities c;
    c.online_cpus = {0, 1};  // fixed: the result must not depend on the machine
    return c;
  }();
  const std::string text(reinterpret_cast<const char*>(data), size);
  rack::HostLoadOptions options;
  options.open_files = false;
  const rack::LoadResult r = rack::load_host_text(text, "fuzz.yaml", *registry, caps, options);
  // Exactly one of: a host, or errors; every error names the file.
  if ((r.host == nullptr) == r.errors.empty()) __builtin_trap();
  for (const auto& e : r.errors) {
    if (e.file != "fuzz.yaml" || e.line < 0 || e.column < 0 || e.message.empty()) __builtin_trap();
    // Messages are clean text (they quote the input): no control byte, bounded.
    for (const char c : e.message) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) __builtin_trap();
    }
    if (e.message.size() > 1024 + 6) __builtin_trap();  // a last UTF-8 sequence and "..."
  }
  return 0;
}
