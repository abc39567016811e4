// libFuzzer harness: gdos record files (rack::gdos_view::RecordReader, what
// `gdos --replay FILE` reads). The reader takes a path, so the bytes go into a memfd
// and the reader opens /proc/self/fd/N: a regular file, as a real one. Invariants: the
// reader throws only FileError (naming the file and a byte offset within it), and
// reads every record of a file or stops at the first bad one.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   tools/gdos/gdos_view.cpp (instrumented); -Itools/gdos -Icore/include -Itims/include
//   -Icore/rt/include; the normal build's librack_core.a librack_tims.a librack_rt.a; -lyaml-cpp -llcm
//   -lzstd -lsodium -ldl.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "gdos_view.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int fd = memfd_create("fuzz-gdos-record", MFD_CLOEXEC);
  if (fd < 0) std::abort();
  if (ftruncate(fd, 0) != 0 || pwrite(fd, data, size, 0) != static_cast<ssize_t>(size)) std::abort();
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  try {
    rack::gdos_view::RecordReader reader(path);
    rack::tims::GdosRecord r;
    std::size_t n = 0;
    while (reader.next(r)) {
      if (++n > size) std::abort();  // each record takes bytes: no endless loop
    }
  } catch (const rack::gdos_view::FileError& e) {
    if (std::string(e.what()).rfind(path + ": byte offset ", 0) != 0 || e.offset() > size) std::abort();
  }
  return 0;
}
