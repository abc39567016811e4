// libFuzzer harness for plug-in manifests (rack::read_plugin_manifest,
// core/src/registry.cpp): the `*.rack-class` files rackd --list-classes and a host
// file's plugins: directories are read from (`class`, `library`, `summary`,
// `interface`, `lock_dependencies` lines). The reader takes a path (it reads the file
// itself, bounded, through rack/rt/input_file.h), so the input is written to a memfd
// and read back through /proc/self/fd/N, as a file on disk would be.
//
// Invariants: a refusal names the file and, for a line, a line of the text
// ("FILE:LINE: why"); an accepted manifest has a class name of 1..63 letters, digits
// or '_', an absolute library path, and no control character in what it kept.
//
// Seeds: tests/fuzz/corpus/plugin_manifest/ (a manifest as rack_add_class writes it,
// one with every key, one with a bad key).
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_support.h"
#include "rack/core/registry.h"

namespace {

bool printable(const std::string& s) {
  for (const char c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int fd = ::memfd_create("fuzz.rack-class", MFD_CLOEXEC);
  FUZZ_CHECK(fd >= 0);
  FUZZ_CHECK(::ftruncate(fd, 0) == 0);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pwrite(fd, data + done, size - done, static_cast<off_t>(done));
    FUZZ_CHECK(n > 0);
    done += static_cast<std::size_t>(n);
  }
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  rack::PluginClassInfo info;
  std::string error;
  if (!rack::read_plugin_manifest(path, info, error)) {
    FUZZ_CHECK(error.rfind(path + ":", 0) == 0);
    const char* after = error.c_str() + path.size() + 1;
    if (*after >= '1' && *after <= '9') {
      std::size_t lines = 1;
      for (std::size_t i = 0; i < size; ++i) lines += data[i] == '\n' ? 1 : 0;
      const auto line = std::strtoull(after, nullptr, 10);
      FUZZ_CHECK(line >= 1 && line <= lines);
    }
    return 0;
  }
  FUZZ_CHECK(!info.impl.empty() && info.impl.size() <= 63);
  for (const char c : info.impl) {
    FUZZ_CHECK((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_');
  }
  FUZZ_CHECK(!info.library.empty() && info.library[0] == '/');
  FUZZ_CHECK(printable(info.library) && printable(info.summary) && printable(info.interface_name));
  FUZZ_CHECK(info.manifest == path);
  return 0;
}
