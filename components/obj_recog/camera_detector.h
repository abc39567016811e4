// Object recognition in camera images, on OpenCV: ArUco fiducials with their 3-D
// pose (cv::aruco, OpenCV 4.6 contrib), and people with OpenCV's HOG detector
// (cv::HOGDescriptor::getDefaultPeopleDetector), written into RACK's object list.
// OpenCV stays behind this header (a pimpl).
//
// Frames: positions in the camera's optical frame (x right, y down, z forward), as
// OpenCV gives them. A person's position is estimated from the box: distance =
// fy * person_height / (person_fraction * box height), i.e. people are assumed to
// stand upright and to be person_height tall; good to some 10-20 %.
//
// Real-time contract: NOT RT-safe (OpenCV allocates); ObjRecogCamera runs it in its
// data task at normal priority. One thread per detector.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "common/camera_calibration.h"
#include "obj_recog_types.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

struct DetectorOptions {
  std::string dictionary = "DICT_4X4_50";  // any of OpenCV's predefined ArUco dictionaries
  double marker_length = 0.15;             // m, the black square's side
  bool fiducials = true;
  bool people = false;
  double person_height = 1.75;   // m
  double person_fraction = 0.8;  // of the HOG box's height that is the person
  double hog_threshold = 0.0;    // SVM score threshold (higher: fewer, surer detections)
  double hog_scale = 1.05;       // image pyramid step
  int hog_max_width = 640;       // larger images are scaled down for HOG (speed)
};

class CameraDetector {
 public:
  // The dictionary names the options take (OpenCV's predefined ArUco dictionaries).
  [[nodiscard]] static std::vector<std::string> dictionary_names();
  // Throws std::invalid_argument for an unknown dictionary or a bad option.
  explicit CameraDetector(const DetectorOptions& options);
  ~CameraDetector();
  CameraDetector(const CameraDetector&) = delete;
  CameraDetector& operator=(const CameraDetector&) = delete;

  // Checks a frame: format RGB8/MONO8/JPEG, a size that matches its byte count.
  // false with `error` naming the field and the values.
  [[nodiscard]] static bool check_frame(const interfaces::CameraData& frame, std::string& error);

  // Detects objects in `frame` with the intrinsics `k` (scaled to the frame's size when
  // it differs with the same aspect ratio). Fills out's object fields (object_count,
  // id, type, probability, position, orientation, size, image area; velocities 0) and
  // frame = kObjFrameCamera. false with `error` for a bad frame (check_frame, JPEG that
  // does not decode, intrinsics for another aspect ratio); `out` is then untouched.
  [[nodiscard]] bool detect(const interfaces::CameraData& frame, const CameraIntrinsics& k,
                            interfaces::ObjRecogData& out, std::string& error);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rack::components
