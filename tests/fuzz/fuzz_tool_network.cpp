// libFuzzer harness for the tools' host-file reader (rack/client/host_file.h,
// client/src/host_file.cpp: libyaml events to a small tree), a decoder of outside
// input: rackctl, gdos and rack-gui read a host file's network with it (--host-file).
// Any bytes go to read_tool_network_text(). It must never crash, hang, throw or
// recurse without bound, and must answer a URL, or errors that name the file.
//
// Seeds: tests/fuzz/corpus/tool_network/ (host files with lcm_url, tims networks,
// anchors and aliases, two documents).
#include <cstddef>
#include <cstdint>
#include <string>

#include "rack/client/host_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const rack::ToolNetwork n = rack::read_tool_network_text(text, "fuzz.yaml");
  if (n.errors.empty() && n.url.empty()) __builtin_trap();  // a usable answer has a URL
  for (const auto& e : n.errors) {
    if (e.file != "fuzz.yaml" || e.line < 0 || e.column < 0 || e.message.empty()) __builtin_trap();
  }
  return 0;
}
