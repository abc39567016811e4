// libFuzzer harness for trajectory files (`t x y theta` lines): the reference file a
// TrajectoryWriter (class TrajectoryWriter, components/evaluator) reads at init()
// (parse_trajectory_text, the text read_trajectory_file reads), then compared with
// itself as the writer compares its estimates (trajectory_error).
//
// Invariants: a refusal is a std::runtime_error "fuzz.txt:LINE: why" with LINE a line
// of the text; poses accepted are finite and in time order; the comparison's counts
// agree (matched <= reference, lost <= matched; poses of the same time may differ, so
// a trajectory need not match itself exactly).
//
// Seeds: tests/fuzz/corpus/trajectory/ (a written trajectory, CRLF, comments).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "evaluator/trajectory_writer.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace c = rack::components;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::vector<c::TimedPose> poses;
  try {
    poses = c::parse_trajectory_text(text, "fuzz.txt");
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    FUZZ_CHECK(what.rfind("fuzz.txt:", 0) == 0);
    const auto line = std::strtoull(what.c_str() + 9, nullptr, 10);
    std::size_t lines = 1;
    for (const char ch : text) lines += ch == '\n' ? 1 : 0;
    FUZZ_CHECK(line >= 1 && line <= lines);
    return 0;
  }
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto& p = poses[i];
    FUZZ_CHECK(std::isfinite(p.t) && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.phi));
    FUZZ_CHECK(i == 0 || poses[i - 1].t <= p.t);
  }
  const c::TrajectoryError e = c::trajectory_error(poses, poses, 0.5, 1.0);
  FUZZ_CHECK(e.reference == poses.size() && e.matched <= e.reference && e.lost <= e.matched);
  return 0;
}
