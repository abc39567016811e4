// libFuzzer harness for the camera calibration file Camera and ObjRecogCamera read
// (`calibration`: components/common/camera_calibration.cpp, parse_camera_calibration,
// on OpenCV's cv::FileStorage in memory: YAML, XML or JSON).
//
// Input: the file's bytes. Properties: only std::runtime_error is thrown (an OpenCV
// exception or anything else would escape the component's init() unnamed), and its
// text names the file; an accepted calibration is for an image of positive size, with
// positive finite focal lengths, a finite centre and 0, 4 or 5 finite distortion
// coefficients: the values every frame of the Camera carries.
//
// It drives parse_camera_calibration_isolated, what rackd uses: OpenCV's parsers are not
// total (a SEGV in its XML reader, an 8 GiB matrix), so each input is parsed in a forked
// child and a crash there must come back as a std::runtime_error. The child's coverage
// does not reach the fuzzer: it mutates blind beyond the seeds (slow, about 1 ms an input),
// so run it long by hand after a change to the reader.
//
// Seeds: tests/fuzz/corpus/calibration/ (OpenCV's calibration sample's output as YAML,
// XML and JSON; one without distortion).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include "common/camera_calibration.h"
#include "fuzz_support.h"

using rack::components::CameraIntrinsics;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  CameraIntrinsics k;
  try {
    k = rack::components::parse_camera_calibration_isolated(text, "cam.yaml");
  } catch (const std::runtime_error& e) {
    FUZZ_CHECK(std::string_view(e.what()).find("'cam.yaml'") != std::string_view::npos);
    return 0;
  } catch (...) {
    rack::fuzz::check_failed("parse_camera_calibration_isolated threw something other than std::runtime_error",
                             __FILE__, __LINE__);
  }
  FUZZ_CHECK(k.valid && k.width > 0 && k.height > 0);
  FUZZ_CHECK(std::isfinite(k.fx) && k.fx > 0.0 && std::isfinite(k.fy) && k.fy > 0.0);
  FUZZ_CHECK(std::isfinite(k.cx) && std::isfinite(k.cy));
  FUZZ_CHECK(k.distortion_count == 0 || k.distortion_count == 4 || k.distortion_count == 5);
  for (const double d : k.distortion) FUZZ_CHECK(std::isfinite(d));
  return 0;
}
