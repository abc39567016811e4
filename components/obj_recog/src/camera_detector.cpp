// The only translation unit of ObjRecog that includes OpenCV.
#include "obj_recog/camera_detector.h"

#include "obj_recog/obj_recog_types.h"

#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace rack::components {

using interfaces::CameraData;
using interfaces::ObjRecogData;

namespace {

struct NamedDictionary {
  const char* name;
  int id;
};
constexpr NamedDictionary kDictionaries[] = {
    {"DICT_4X4_50", cv::aruco::DICT_4X4_50},
    {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
    {"DICT_4X4_250", cv::aruco::DICT_4X4_250},
    {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
    {"DICT_5X5_50", cv::aruco::DICT_5X5_50},
    {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
    {"DICT_5X5_250", cv::aruco::DICT_5X5_250},
    {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
    {"DICT_6X6_50", cv::aruco::DICT_6X6_50},
    {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
    {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
    {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
    {"DICT_7X7_50", cv::aruco::DICT_7X7_50},
    {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
    {"DICT_7X7_250", cv::aruco::DICT_7X7_250},
    {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
    {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
    {"DICT_APRILTAG_16h5", cv::aruco::DICT_APRILTAG_16h5},
    {"DICT_APRILTAG_25h9", cv::aruco::DICT_APRILTAG_25h9},
    {"DICT_APRILTAG_36h10", cv::aruco::DICT_APRILTAG_36h10},
    {"DICT_APRILTAG_36h11", cv::aruco::DICT_APRILTAG_36h11},
};

}  // namespace

std::vector<std::string> CameraDetector::dictionary_names() {
  std::vector<std::string> names;
  for (const auto& d : kDictionaries) names.emplace_back(d.name);
  return names;
}

struct CameraDetector::Impl {
  DetectorOptions options;
  cv::Ptr<cv::aruco::Dictionary> dictionary;
  cv::Ptr<cv::aruco::DetectorParameters> parameters;
  cv::HOGDescriptor hog;
  cv::Mat gray, decoded, small;
  std::vector<int> ids;
  std::vector<std::vector<cv::Point2f>> corners, rejected;
  std::vector<cv::Vec3d> rvecs, tvecs;
  std::vector<cv::Rect> boxes;
  std::vector<double> weights;
};

CameraDetector::CameraDetector(const DetectorOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.options = options;
  int dict = -1;
  for (const auto& d : kDictionaries) {
    if (options.dictionary == d.name) dict = d.id;
  }
  if (dict < 0)
    throw std::invalid_argument("unknown ArUco dictionary '" + options.dictionary +
                                "' (e.g. DICT_4X4_50, DICT_6X6_250, DICT_APRILTAG_36h11)");
  if (!(options.marker_length > 0.0)) throw std::invalid_argument("marker_length must be > 0");
  if (!(options.person_height > 0.0) || !(options.person_fraction > 0.0 && options.person_fraction <= 1.0)) {
    throw std::invalid_argument("person_height must be > 0 and person_fraction in (0, 1]");
  }
  if (!(options.hog_scale > 1.0)) throw std::invalid_argument("hog_scale must be > 1");
  m.dictionary = cv::aruco::getPredefinedDictionary(dict);
  m.parameters = cv::aruco::DetectorParameters::create();
  m.parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;  // better poses
  if (options.people) m.hog.setSVMDetector(cv::HOGDescriptor::getDefaultPeopleDetector());
}

CameraDetector::~CameraDetector() = default;

bool CameraDetector::check_frame(const CameraData& f, std::string& error) {
  if (f.format != interfaces::kCameraRgb8 && f.format != interfaces::kCameraMono8 &&
      f.format != interfaces::kCameraJpeg) {
    error = "format " + std::to_string(f.format) + " is not RGB8 (1), MONO8 (2) or JPEG (3)";
    return false;
  }
  if (f.width == 0 || f.height == 0 || f.width > 16384 || f.height > 16384) {
    error = "size " + std::to_string(f.width) + "x" + std::to_string(f.height) + " is not an image";
    return false;
  }
  if (f.bytes == 0 || f.bytes > interfaces::kCameraMaxBytes) {
    error = "bytes " + std::to_string(f.bytes) + " outside 1.." + std::to_string(interfaces::kCameraMaxBytes);
    return false;
  }
  if (f.format != interfaces::kCameraJpeg) {
    const uint64_t need = uint64_t{f.width} * f.height * (f.format == interfaces::kCameraRgb8 ? 3U : 1U);
    if (need != f.bytes) {
      error = std::string(f.format == interfaces::kCameraRgb8 ? "RGB8" : "MONO8") + " frame " +
              std::to_string(f.width) + "x" + std::to_string(f.height) + " needs " + std::to_string(need) +
              " bytes, has " + std::to_string(f.bytes);
      return false;
    }
  }
  return true;
}

bool CameraDetector::detect(const CameraData& f, const CameraIntrinsics& k0, ObjRecogData& out, std::string& error) {
  if (!check_frame(f, error)) return false;
  Impl& m = *impl_;
  const DetectorOptions& o = m.options;
  const int w = static_cast<int>(f.width), h = static_cast<int>(f.height);
  // Mutable image data: OpenCV's Mat wraps it without copying (read only here).
  auto* data = const_cast<uint8_t*>(f.data);
  if (f.format == interfaces::kCameraRgb8) {
    cv::cvtColor(cv::Mat(h, w, CV_8UC3, data), m.gray, cv::COLOR_RGB2GRAY);
  } else if (f.format == interfaces::kCameraMono8) {
    cv::Mat(h, w, CV_8UC1, data).copyTo(m.gray);
  } else {
    m.gray = cv::imdecode(cv::Mat(1, static_cast<int>(f.bytes), CV_8UC1, data), cv::IMREAD_GRAYSCALE);
    if (m.gray.empty()) {
      error = "JPEG frame (" + std::to_string(f.bytes) + " bytes) does not decode";
      return false;
    }
    if (m.gray.cols != w || m.gray.rows != h) {
      error = "JPEG decodes to " + std::to_string(m.gray.cols) + "x" + std::to_string(m.gray.rows) +
              ", the frame says " + std::to_string(w) + "x" + std::to_string(h);
      return false;
    }
  }
  // Intrinsics for this frame's size (same aspect ratio: scale; otherwise refuse).
  CameraIntrinsics k = k0;
  if (k.valid && (k.width != w || k.height != h)) {
    const double sx = static_cast<double>(w) / k.width, sy = static_cast<double>(h) / k.height;
    if (std::fabs(sx - sy) > 0.01 * sx) {
      error = "frame " + std::to_string(w) + "x" + std::to_string(h) +
              " has another aspect ratio than the calibration (" + std::to_string(k.width) + "x" +
              std::to_string(k.height) + ")";
      return false;
    }
    k.fx *= sx;
    k.cx *= sx;
    k.fy *= sy;
    k.cy *= sy;
  }
  uint32_t n = 0;
  const auto add = [&](uint32_t id, uint8_t type, float probability, const cv::Rect& box) -> bool {
    if (n >= interfaces::kObjRecogMaxObjects) return false;
    out.id[n] = id;
    out.type[n] = type;
    out.probability[n] = probability;
    out.image_x[n] = box.x;
    out.image_y[n] = box.y;
    out.image_width[n] = box.width;
    out.image_height[n] = box.height;
    out.vx[n] = out.vy[n] = out.vz[n] = 0.0F;
    out.roll[n] = out.pitch[n] = out.yaw[n] = 0.0F;
    out.x[n] = out.y[n] = out.z[n] = 0.0F;
    return true;
  };
  const cv::Matx33d camera(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  const cv::Mat dist(1, 5, CV_64F, k.distortion);
  if (o.fiducials) {
    m.ids.clear();
    m.corners.clear();
    cv::aruco::detectMarkers(m.gray, m.dictionary, m.corners, m.ids, m.parameters, m.rejected);
    if (!m.ids.empty() && k.valid) {
      cv::aruco::estimatePoseSingleMarkers(m.corners, static_cast<float>(o.marker_length), camera, dist, m.rvecs,
                                           m.tvecs);
    }
    for (std::size_t i = 0; i < m.ids.size(); ++i) {
      if (!add(static_cast<uint32_t>(m.ids[i]), interfaces::kObjTypeFiducial, 1.0F, cv::boundingRect(m.corners[i])))
        break;
      if (k.valid) {
        const cv::Vec3d& t = m.tvecs[i];
        cv::Matx33d r;
        cv::Rodrigues(m.rvecs[i], r);
        out.x[n] = static_cast<float>(t[0]);
        out.y[n] = static_cast<float>(t[1]);
        out.z[n] = static_cast<float>(t[2]);
        // ZYX Euler angles of the marker's frame (x right, y up, z out of the marker) in the camera frame.
        out.yaw[n] = static_cast<float>(std::atan2(r(1, 0), r(0, 0)));
        out.pitch[n] = static_cast<float>(std::asin(std::clamp(-r(2, 0), -1.0, 1.0)));
        out.roll[n] = static_cast<float>(std::atan2(r(2, 1), r(2, 2)));
      }
      out.size_x[n] = out.size_y[n] = static_cast<float>(o.marker_length);
      out.size_z[n] = 0.0F;
      ++n;
    }
  }
  if (o.people) {
    double scale = 1.0;
    const cv::Mat* img = &m.gray;
    if (w > o.hog_max_width && o.hog_max_width > 0) {
      scale = static_cast<double>(o.hog_max_width) / w;
      cv::resize(m.gray, m.small, cv::Size(), scale, scale, cv::INTER_AREA);
      img = &m.small;
    }
    m.boxes.clear();
    m.weights.clear();
    m.hog.detectMultiScale(*img, m.boxes, m.weights, o.hog_threshold, cv::Size(8, 8), cv::Size(8, 8), o.hog_scale, 2.0);
    for (std::size_t i = 0; i < m.boxes.size(); ++i) {
      const cv::Rect& s = m.boxes[i];
      const cv::Rect box(static_cast<int>(s.x / scale), static_cast<int>(s.y / scale),
                         static_cast<int>(s.width / scale), static_cast<int>(s.height / scale));
      const double weight = i < m.weights.size() ? m.weights[i] : 0.0;
      if (!add(0, interfaces::kObjTypePerson, static_cast<float>(1.0 / (1.0 + std::exp(-weight))), box)) break;
      if (k.valid && box.height > 0) {
        const double z = k.fy * o.person_height / (o.person_fraction * box.height);
        const double u = box.x + box.width / 2.0, v = box.y + box.height / 2.0;
        out.x[n] = static_cast<float>((u - k.cx) * z / k.fx);
        out.y[n] = static_cast<float>((v - k.cy) * z / k.fy);
        out.z[n] = static_cast<float>(z);
        out.size_x[n] = static_cast<float>(box.width * o.person_fraction * z / k.fx);
        out.size_y[n] = static_cast<float>(o.person_height);
        out.size_z[n] = 0.3F;
      }
      ++n;
    }
  }
  out.object_count = n;
  out.frame = interfaces::kObjFrameCamera;
  return true;
}

}  // namespace rack::components
