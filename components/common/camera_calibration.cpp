#include "common/camera_calibration.h"

#include "rack/rt/input_file.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <stdexcept>

namespace rack::components {

namespace {
// An OpenCV calibration file holds a few matrices: kilobytes.
constexpr uint64_t kMaxCalibrationBytes = 16u << 20;
}  // namespace

CameraIntrinsics parse_camera_calibration(std::string_view text, const std::string& name) {
  const auto fail = [&name](const std::string& why) {
    return std::runtime_error("calibration '" + name + "': " + why);
  };
  // A text file: OpenCV's XML parser dereferenced a null pointer on a NUL byte in its
  // header (SEGV, found by fuzz_calibration); no YAML, XML or JSON text holds one.
  if (const auto nul = text.find('\0'); nul != std::string_view::npos) {
    throw fail("byte " + std::to_string(nul) + " is a NUL: not a YAML, XML or JSON text");
  }
  cv::Mat km, dm;
  CameraIntrinsics k;
  bool opened = false;
  try {
    cv::FileStorage fs(std::string(text), cv::FileStorage::READ | cv::FileStorage::MEMORY);
    opened = fs.isOpened();
    if (opened) {
      fs["camera_matrix"] >> km;
      fs["distortion_coefficients"] >> dm;
      fs["image_width"] >> k.width;
      fs["image_height"] >> k.height;
    }
  } catch (const std::exception& e) {
    // cv::Exception, and the standard library's own: OpenCV's YAML parser threw
    // std::length_error on a text found by fuzz_calibration.
    throw fail(e.what());
  }
  if (!opened) throw fail("cannot parse it (not OpenCV's YAML, XML or JSON)");
  if (km.rows != 3 || km.cols != 3) throw fail("camera_matrix missing or not 3x3");
  if (k.width <= 0 || k.height <= 0) throw fail("image_width/image_height missing");
  km.convertTo(km, CV_64F);
  k.fx = km.at<double>(0, 0);
  k.fy = km.at<double>(1, 1);
  k.cx = km.at<double>(0, 2);
  k.cy = km.at<double>(1, 2);
  if (!(k.fx > 0.0) || !(k.fy > 0.0)) throw fail("camera_matrix focal lengths must be > 0");
  if (!dm.empty()) {
    dm.convertTo(dm, CV_64F);
    if (dm.total() < 4) throw fail("distortion_coefficients needs 4 or 5 values");
    k.distortion_count = static_cast<int>(std::min<std::size_t>(5, dm.total()));
    for (int i = 0; i < k.distortion_count; ++i) k.distortion[i] = dm.at<double>(i);
  }
  k.valid = true;
  return k;
}

CameraIntrinsics load_camera_calibration(const std::string& path) {
  std::string text, error;
  if (!rt::read_regular_file(path, kMaxCalibrationBytes, "calibration file", text, error)) {
    throw std::runtime_error("calibration: " + error);
  }
  return parse_camera_calibration(text, path);
}

}  // namespace rack::components
