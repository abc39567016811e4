// ObjRecogCamera (class ObjRecog): objects in a Camera component's images, on OpenCV
// (obj_recog/camera_detector.h): ArUco fiducials with their 3-D pose, and people with
// OpenCV's HOG detector, as RACK's object list in the camera frame. Velocities come
// from the previous image: a fiducial by its id, a person by the nearest previous
// person within `person_gate` (people get ids from 1000 up, kept while they are
// followed).
//
// Intrinsics: from the `calibration` file (OpenCV FileStorage: camera_matrix,
// distortion_coefficients, image_width, image_height), else from the frames (the
// Camera component publishes its calibration with every frame). Without either,
// objects are still found (ids, image areas) but have no position.
//
// Bad input, skipped and counted (ObjRecogData.bad_input) with a logged reason (the
// first, then every 100th), because the next frame may be fine: a DATA message that
// is not a CameraData (also counted as malformed in GET_STATS, logged once a second
// by the input path), a frame of the wrong format, a size that does not match its byte count, a size other than `width` x
// `height` (when given), a JPEG that does not decode, a size with another aspect
// ratio than the calibration. A calibration file that cannot be read is a
// configuration error: init() fails and the component stays in ERROR with the file
// and key. The Camera (a declared input: camera, camera_period_ms) going silent for
// silence_ms puts it in ERROR (on() retries).
//
// Scheduling: OpenCV allocates: run the DATA task at priority 0 (normal scheduling),
// as MCL's; loop() is NOT RT-safe. on()/off() only exchange messages.
#pragma once

#include <memory>
#include <string>

#include "rack/core/data_component.h"
#include "obj_recog_types.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

class CameraDetector;
struct CameraIntrinsics;

class ObjRecogCamera final : public DataComponent<interfaces::ObjRecogData> {
 public:
  ObjRecogCamera();
  ~ObjRecogCamera() override;

  // Velocities and person ids from the previous sample (pure; for tests). `prev` is the
  // previous output at prev_time_ns (object_count 0: none); `next_person_id` is advanced.
  static void follow(const interfaces::ObjRecogData& prev, int64_t prev_time_ns, interfaces::ObjRecogData& cur,
                     int64_t time_ns, double person_gate, uint32_t& next_person_id) noexcept;

 protected:
  void init() override;
  HookResult on() override;
  HookResult loop() override;  // NOT RT-safe: OpenCV

 private:
  void count_bad(const std::string& why);

  InputOf<interfaces::CameraData>& camera_;  // the newest frame is its value()
  Parameter& calibration_;
  Parameter& width_;
  Parameter& height_;
  Parameter& dictionary_;
  Parameter& marker_length_;
  Parameter& fiducials_;
  Parameter& people_;
  Parameter& person_height_;
  Parameter& hog_threshold_;
  Parameter& person_gate_;

  std::unique_ptr<CameraDetector> detector_;
  std::unique_ptr<CameraIntrinsics> file_intrinsics_;
  std::unique_ptr<interfaces::ObjRecogData> out_, prev_;
  int64_t prev_time_ns_ = 0;
  uint32_t next_person_id_ = 1000;
  uint32_t bad_ = 0, inputs_ = 0;
};

}  // namespace rack::components
