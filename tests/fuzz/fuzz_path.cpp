// libFuzzer harness for the Path class's waypoints (components/path/path.cpp): the
// `waypoints` parameter text (Path::parse_waypoints; from a host file or `rackctl
// set-param path waypoints ...`) and the MAKE command's PathMake body from the network
// (Path::make_path), each followed by the spline the data task would publish.
//
// Input: one byte of mode (bit 0: a text, else a MAKE body), two bytes of resolution
// (the parameter's range, 0.01..10 m), then the text (cut at the parameter's length)
// or the body's fields (count, closed, x[32], y[32]: any bits, the count unchecked, as
// read_payload hands them over). Invariants: a refusal has a reason; a text accepted
// has 1..32 finite waypoints; a path made has at most 2048 points, every point and
// waypoint finite as the float the sample carries (a double past FLT_MAX narrowed to
// float is undefined behaviour: UBSan), and a finite length.
//
// Seeds: tests/fuzz/corpus/path/ (texts of configs/, a closed loop, a MAKE body).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "fuzz_support.h"
#include "path/path.h"
#include "rack/core/wire.h"

namespace {

using rack::components::Path;
using rack::interfaces::PathData;
using rack::interfaces::PathMake;

PathData g_out;  // 17 KB: kept off the stack, as the component keeps it in a member

void check_made(const PathMake& w, const char* why) {
  if (why != nullptr) {
    FUZZ_CHECK(*why != '\0');
    return;
  }
  FUZZ_CHECK(g_out.waypoint_count == w.count && w.count >= 2 && w.count <= rack::interfaces::kPathMaxWaypoints);
  FUZZ_CHECK(g_out.point_count >= 1 && g_out.point_count <= rack::interfaces::kPathMaxPoints);
  FUZZ_CHECK(std::isfinite(g_out.length) && g_out.length >= 0.0);
  for (uint32_t i = 0; i < g_out.waypoint_count; ++i) {
    FUZZ_CHECK(std::isfinite(g_out.waypoint_x[i]) && std::isfinite(g_out.waypoint_y[i]));
  }
  for (uint32_t i = 0; i < g_out.point_count; ++i) FUZZ_CHECK(std::isfinite(g_out.x[i]) && std::isfinite(g_out.y[i]));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const uint8_t mode = in.byte();
  const double resolution = 0.01 + 9.99 * static_cast<double>(in.take<uint16_t>()) / 65535.0;
  PathMake w;
  if ((mode & 1) != 0) {
    // The parameter's text: at most kParamStringLen - 1 characters, NUL-terminated.
    char text[rack::wire::kParamStringLen] = {};
    const auto bytes = in.bytes(sizeof text - 1);
    if (!bytes.empty()) std::memcpy(text, bytes.data(), bytes.size());
    int item = -1;
    const char* why = Path::parse_waypoints(text, w, item);
    if (why != nullptr) {
      FUZZ_CHECK(*why != '\0' && item >= 0 && item <= static_cast<int>(rack::interfaces::kPathMaxWaypoints) + 1);
      return 0;
    }
    FUZZ_CHECK(item == 0 && w.count >= 1 && w.count <= rack::interfaces::kPathMaxWaypoints);
    for (uint32_t i = 0; i < w.count; ++i) FUZZ_CHECK(std::isfinite(w.x[i]) && std::isfinite(w.y[i]));
    w.closed = (mode & 2) != 0 ? 1 : 0;
  } else {
    w.count = in.take<uint32_t>();
    w.closed = in.byte();
    for (double& x : w.x) x = in.take<double>();
    for (double& y : w.y) y = in.take<double>();
  }
  check_made(w, Path::make_path(w, resolution, g_out));
  return 0;
}
