// libFuzzer harness: PCD point clouds (rack::scan3d::parse_pcd, the bytes read_pcd
// reads). Invariants: a cloud's four columns have one length, no more points than
// declared, all coordinates finite; a refusal says why, naming the file.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   components/scan3d/src/pcd_file.cpp core/rt/src/input_file.cpp; -Icomponents/scan3d/include
//   -Icomponents/interfaces/include -Icore/include -Itims/include -Icore/rt/include.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <string>

#include "rack/scan3d/pcd_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  rack::scan3d::PcdCloud cloud;
  std::string error;
  const bool ok = rack::scan3d::parse_pcd("fuzz.pcd", bytes, cloud, error);
  if (ok) {
    const std::size_t n = cloud.x.size();
    if (cloud.y.size() != n || cloud.z.size() != n || cloud.intensity.size() != n) std::abort();
    if (n + cloud.non_finite != cloud.declared_points) std::abort();
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(cloud.x[i]) || !std::isfinite(cloud.y[i]) || !std::isfinite(cloud.z[i])) std::abort();
    }
  } else if (error.rfind("fuzz.pcd", 0) != 0) {
    std::abort();
  }
  return 0;
}
