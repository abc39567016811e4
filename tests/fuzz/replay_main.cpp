// The replay driver of the normal (GCC) build: runs a harness over every file of the
// folders (or files) it is given, in name order, so every seed and every regression
// input is decoded on every CI run and the harnesses cannot rot. The libFuzzer build
// links libFuzzer's own main instead (tests/fuzz/run).
//
//   fuzz_nmea tests/fuzz/corpus/nmea tests/fuzz/regressions/nmea
//
// A folder that does not exist is skipped (a harness may have no regressions yet); the
// run fails when no input was found at all, so a harness cannot pass on nothing.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

bool replay(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "replay: cannot read %s\n", file.c_str());
    return false;
  }
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // A copy of exactly the file's size, so a read past its end is past an allocation.
  std::vector<uint8_t> data(bytes.begin(), bytes.end());
  std::fprintf(stderr, "replay: %s (%zu bytes)\n", file.c_str(), data.size());
  (void)LLVMFuzzerTestOneInput(data.empty() ? nullptr : data.data(), data.size());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help") {
    std::fprintf(stderr,
                 "usage: %s FOLDER|FILE...\nRuns this fuzz harness once over every file given "
                 "(folders: every regular file in them, in name order).\n",
                 argv[0]);
    return argc < 2 ? 2 : 0;
  }
  std::size_t inputs = 0;
  for (int i = 1; i < argc; ++i) {
    const std::filesystem::path p(argv[i]);
    std::error_code ec;
    if (std::filesystem::is_directory(p, ec)) {
      std::vector<std::filesystem::path> files;
      for (const auto& e : std::filesystem::directory_iterator(p)) {
        if (e.is_regular_file()) files.push_back(e.path());
      }
      std::sort(files.begin(), files.end());
      for (const auto& f : files) {
        if (!replay(f)) return 1;
        ++inputs;
      }
    } else if (std::filesystem::is_regular_file(p, ec)) {
      if (!replay(p)) return 1;
      ++inputs;
    } else {
      std::fprintf(stderr, "replay: %s does not exist (skipped)\n", p.c_str());
    }
  }
  if (inputs == 0) {
    std::fprintf(stderr, "replay: no input found: a harness needs at least one seed\n");
    return 1;
  }
  std::fprintf(stderr, "replay: %zu input(s), no crash\n", inputs);
  return 0;
}
