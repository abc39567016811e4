// libFuzzer harness for the plug-in ABI stamp reader (rack::plugin_abi::read_stamp,
// core/src/plugin_abi.cpp), which reads the first bytes of every plug-in file rackd is
// asked to load, before dlopen(): the ELF header, the program headers and the notes of
// each PT_NOTE segment. Invariants: never reads outside the buffer (ASan); a stamp
// found is 1..63 printable characters; a refusal says why, an absent stamp says nothing.
//
// Seeds: tests/fuzz/corpus/plugin_abi/ (the first 2 KiB of a stamped and of an
// unstamped plug-in of this tree, and a cut-short ELF header).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "fuzz_support.h"
#include "rack/core/plugin_abi.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace abi = rack::plugin_abi;
  std::string stamp, why;
  const auto r = abi::read_stamp(std::span<const std::byte>(reinterpret_cast<const std::byte*>(data), size), stamp,
                                 why);
  switch (r) {
    case abi::StampRead::kFound:
      FUZZ_CHECK(!stamp.empty() && stamp.size() < abi::kStampBytes && why.empty());
      for (const char c : stamp) FUZZ_CHECK(c >= 0x20 && c < 0x7f);
      (void)abi::describe_stamp(stamp);
      break;
    case abi::StampRead::kAbsent: FUZZ_CHECK(stamp.empty() && why.empty()); break;
    case abi::StampRead::kMalformed: FUZZ_CHECK(!why.empty()); break;
  }
  return 0;
}
