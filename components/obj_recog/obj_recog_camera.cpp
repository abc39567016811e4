#include "obj_recog/obj_recog_camera.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "obj_recog/camera_detector.h"

namespace rack::components {

using interfaces::CameraData;
using interfaces::ObjRecogData;

ObjRecogCamera::ObjRecogCamera()
    : DataComponent(DataTaskMode::kTriggered),
      camera_(declare_input<CameraData>("camera", {.doc = "the Camera whose images are searched",
                                                   .ask_period = true,
                                                   .old_period_name = "period_ms"})),
      calibration_(declare_string("calibration", "",
                                  {.doc = "OpenCV calibration file (empty: the calibration in the Camera's frames)",
                                   .init_only = true,
                                   .path = PathRole::kInput})),
      width_(declare_int("width", 0,
                         {.doc = "expected image width; other sizes are skipped (0: any)", .min = 0, .max = 16384})),
      height_(declare_int("height", 0, {.doc = "expected image height (0: any)", .min = 0, .max = 16384})),
      dictionary_(declare_string("dictionary", "DICT_4X4_50",
                                 {.doc = "ArUco dictionary (OpenCV's names: DICT_4X4_50 ... DICT_APRILTAG_36h11)",
                                  .choices = CameraDetector::dictionary_names(),
                                  .init_only = true})),
      marker_length_(
          declare_float("marker_length", 0.15,
                        {.doc = "m, side of the markers' black square", .min = 1e-4, .max = 100.0, .init_only = true})),
      fiducials_(declare_bool("fiducials", true, {.doc = "find ArUco markers", .init_only = true})),
      people_(declare_bool("people", false,
                           {.doc = "find people (HOG; about 0.1-0.5 s per 640x480 image)", .init_only = true})),
      person_height_(declare_float(
          "person_height", 1.75,
          {.doc = "m, assumed height of a person (distance from the box)", .min = 0.1, .max = 3.0, .init_only = true})),
      hog_threshold_(declare_float("hog_threshold", 0.0,
                                   {.doc = "HOG SVM score threshold (higher: fewer false detections)",
                                    .min = -10.0,
                                    .max = 10.0,
                                    .init_only = true})),
      person_gate_(declare_float(
          "person_gate", 0.7,
          {.doc = "m, a person this close to one in the previous image is the same", .min = 0.01, .max = 100.0})) {}

ObjRecogCamera::~ObjRecogCamera() = default;

void ObjRecogCamera::init() {
  DetectorOptions o;
  o.dictionary = dictionary_.get_string();
  o.marker_length = marker_length_.get_float();
  o.fiducials = fiducials_.get_bool();
  o.people = people_.get_bool();
  o.person_height = person_height_.get_float();
  o.hog_threshold = hog_threshold_.get_float();
  try {
    detector_ = std::make_unique<CameraDetector>(o);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("parameters: ") + e.what());
  }
  const std::string calib = calibration_.get_string();
  if (!calib.empty()) file_intrinsics_ = std::make_unique<CameraIntrinsics>(load_camera_calibration(calib));
  out_ = std::make_unique<ObjRecogData>();
  prev_ = std::make_unique<ObjRecogData>();
}

HookResult ObjRecogCamera::on() {  // the camera is on and subscribed already (declared input)
  prev_->object_count = 0;
  bad_ = inputs_ = 0;
  return HookResult::kOk;
}

void ObjRecogCamera::count_bad(const std::string& why) {
  ++bad_;
  if (bad_ == 1 || bad_ % 100 == 0) log_warning("skipped an image: %s (%u so far)", why.c_str(), bad_);
}

void ObjRecogCamera::follow(const ObjRecogData& prev, int64_t prev_time_ns, ObjRecogData& cur, int64_t time_ns,
                            double person_gate, uint32_t& next_person_id) noexcept {
  const double dt = static_cast<double>(time_ns - prev_time_ns) * 1e-9;
  bool used[interfaces::kObjRecogMaxObjects] = {};
  for (uint32_t i = 0; i < cur.object_count; ++i) {
    int match = -1;
    if (cur.type[i] == interfaces::kObjTypeFiducial) {
      for (uint32_t j = 0; j < prev.object_count; ++j) {
        if (prev.type[j] == interfaces::kObjTypeFiducial && prev.id[j] == cur.id[i]) match = static_cast<int>(j);
      }
    } else if (cur.type[i] == interfaces::kObjTypePerson) {
      double best = person_gate;
      for (uint32_t j = 0; j < prev.object_count; ++j) {
        if (prev.type[j] != interfaces::kObjTypePerson || used[j]) continue;
        const double d = std::hypot(std::hypot(cur.x[i] - prev.x[j], cur.y[i] - prev.y[j]), cur.z[i] - prev.z[j]);
        if (d < best) {
          best = d;
          match = static_cast<int>(j);
        }
      }
      cur.id[i] = match >= 0 ? prev.id[static_cast<uint32_t>(match)] : next_person_id++;
    }
    if (match < 0 || !(dt > 1e-6) || dt > 5.0) continue;
    const auto j = static_cast<uint32_t>(match);
    used[j] = true;
    const auto inv = static_cast<float>(1.0 / dt);
    cur.vx[i] = (cur.x[i] - prev.x[j]) * inv;
    cur.vy[i] = (cur.y[i] - prev.y[j]) * inv;
    cur.vz[i] = (cur.z[i] - prev.z[j]) * inv;
  }
}

HookResult ObjRecogCamera::loop() {
  // Only the newest image counts: recognition must not lag behind the camera. A DATA
  // message of the wrong size for CameraData is skipped (logged and counted in
  // GET_STATS malformed by the input path) and counted as bad input here.
  const uint64_t malformed_before = camera_.malformed();
  wire::SampleHeader sh{};
  const Received r = receive([&](const InputPort& in) { sh = in.sample_header(); });
  bad_ += static_cast<uint32_t>(camera_.malformed() - malformed_before);
  if (r.failed) return HookResult::kError;  // the camera left ENABLED or fell silent: re-subscribed on retry
  if (r.samples == 0) return HookResult::kOk;
  const auto start = std::chrono::steady_clock::now();
  const CameraData& f = camera_.value();
  const int64_t want_w = width_.get_int(), want_h = height_.get_int();
  if ((want_w > 0 && f.width != static_cast<uint64_t>(want_w)) ||
      (want_h > 0 && f.height != static_cast<uint64_t>(want_h))) {
    count_bad("size " + std::to_string(f.width) + "x" + std::to_string(f.height) + ", expected " +
              std::to_string(want_w) + "x" + std::to_string(want_h) + " (parameters width/height)");
    out_->bad_input = bad_;
    return HookResult::kOk;
  }
  CameraIntrinsics k;
  if (file_intrinsics_) {
    k = *file_intrinsics_;
  } else if (f.calibrated != 0) {
    k.valid = true;
    k.width = static_cast<int>(f.width);
    k.height = static_cast<int>(f.height);
    k.fx = f.fx;
    k.fy = f.fy;
    k.cx = f.cx;
    k.cy = f.cy;
    for (int i = 0; i < 5; ++i) k.distortion[i] = f.distortion[i];
  }
  std::string error;
  ObjRecogData& d = *out_;
  if (!detector_->detect(f, k, d, error)) {
    count_bad(error);
    d.bad_input = bad_;
    return HookResult::kOk;
  }
  follow(*prev_, prev_time_ns_, d, sh.time_ns, person_gate_.get_float(), next_person_id_);
  d.inputs = ++inputs_;
  d.bad_input = bad_;
  d.process_ms = std::chrono::duration<float, std::milli>(std::chrono::steady_clock::now() - start).count();
  publish(d, sh.time_ns);
  *prev_ = d;
  prev_time_ns_ = sh.time_ns;
  return HookResult::kOk;
}

}  // namespace rack::components
