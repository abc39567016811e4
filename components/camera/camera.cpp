#include "camera.h"

#include "common/camera_calibration.h"
#include "rack/rt/input_file.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace rack::components {

namespace {

// "frames/img_%04d.png" or "rtsp://...": not one file of that name.
bool is_pattern_or_url(const std::string& src) {
  return src.find('%') != std::string::npos || src.find("://") != std::string::npos;
}

}  // namespace

using interfaces::CameraData;

struct Camera::Capture {
  cv::VideoCapture video;
  cv::Mat frame, converted, scaled;
  std::vector<uchar> jpeg;
  // Calibration as loaded (for the calibration image size).
  bool calibrated = false;
  double fx = 0, fy = 0, cx = 0, cy = 0, dist[5] = {};
  int calib_width = 0, calib_height = 0;
  int back = 2;  // the buffer the thread fills
};

Camera::Camera()
    : DataComponent(DataTaskMode::kPeriodic),
      source_(declare_string(
          "source", "",
          {.doc =
               "V4L2 device (/dev/video0 or 0), video file, or image sequence (img_%04d.png); relative: to the host file's folder",
           .required = true,
           .path = PathRole::kDevice})),
      width_(declare_int("width", 0, {.doc = "requested width (0: the source's)", .min = 0, .max = 8192})),
      height_(declare_int("height", 0, {.doc = "requested height (0: the source's)", .min = 0, .max = 8192})),
      fps_(declare_float("fps", 0.0, {.doc = "requested frame rate (0: the source's)", .min = 0.0, .max = 1000.0})),
      format_(declare_string("format", "rgb",
                             {.doc = "rgb, mono or jpeg (for remote viewing)", .choices = {"rgb", "mono", "jpeg"}})),
      jpeg_quality_(declare_int("jpeg_quality", 80, {.doc = "JPEG quality 1..100", .min = 1, .max = 100})),
      loop_file_(declare_bool("loop", false, {.doc = "start a video file or image sequence again at its end"})),
      calibration_(declare_string("calibration", "",
                                  {.doc = "OpenCV calibration file (camera_matrix, distortion_coefficients)",
                                   .init_only = true,
                                   .path = PathRole::kInput})),
      device_timeout_ms_(declare_float(
          "device_timeout_ms", 2000.0,
          {.doc = "ERROR when the source delivered no frame for this long (and on() waits this long for it)",
           .min = 1.0,
           .max = 3.6e6,
           .unit = "ms"})) {
  parameters().add_old_name("timeout_ms", "device_timeout_ms");  // docs/parameters.md
}

Camera::~Camera() { cleanup(); }

void Camera::init() {
  // format: rgb, mono or jpeg (its Spec's choices, checked wherever it is set).
  capture_ = std::make_unique<Capture>();
  buffers_ = std::make_unique<CameraData[]>(3);  // 3 x 0.9 MB, allocated once
  const std::string calib = calibration_.get_string();
  if (!calib.empty()) {
    const CameraIntrinsics k = load_camera_calibration(calib);
    if (k.distortion_count == 0) {
      throw std::runtime_error("calibration '" + calib +
                               "': needs camera_matrix (3x3), distortion_coefficients (4 or 5) and image_width/height");
    }
    capture_->calib_width = k.width;
    capture_->calib_height = k.height;
    capture_->fx = k.fx;
    capture_->fy = k.fy;
    capture_->cx = k.cx;
    capture_->cy = k.cy;
    std::copy(std::begin(k.distortion), std::end(k.distortion), std::begin(capture_->dist));
    capture_->calibrated = true;
  }
  quit_ = false;
  // The capture blocks in OpenCV: an executor-owned I/O worker runs it (not RT).
  add_io_worker(
      "camera-capture", [this] { run(); },
      [this] {
        quit_.store(true, std::memory_order_release);
        capturing_.store(false, std::memory_order_release);
      });
}

void Camera::cleanup() {
  // The executor has stopped and joined the capture worker before cleanup().
  quit_ = true;
  capturing_ = false;
}

HookResult Camera::on() {
  open_state_.store(0, std::memory_order_relaxed);
  bad_frames_.store(0, std::memory_order_relaxed);
  delivered_.store(0, std::memory_order_relaxed);
  ended_.store(0, std::memory_order_relaxed);
  published_frames_ = 0;
  capturing_.store(true, std::memory_order_release);
  // Wait (bounded) for the capture thread to open the source.
  const auto timeout = static_cast<int64_t>(device_timeout_ms_.get_float() * 1e6);
  const int64_t end = rt::monotonic_ns() + timeout;
  while (open_state_.load(std::memory_order_acquire) == 0 && rt::monotonic_ns() < end) rt::sleep_for(rt::kNsPerMs);
  if (open_state_.load(std::memory_order_acquire) != 1) {
    capturing_.store(false, std::memory_order_release);
    return HookResult::kError;
  }
  last_frame_ns_ = rt::monotonic_ns();
  return HookResult::kOk;
}

void Camera::off() { capturing_.store(false, std::memory_order_release); }

HookResult Camera::loop() {
  const uint8_t m = middle_.load(std::memory_order_acquire);
  if ((m & kFresh) != 0) {
    const uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & static_cast<uint8_t>(~kFresh);
    CameraData& d = buffers_[front_];
    d.dropped = delivered_.load(std::memory_order_relaxed) - ++published_frames_;
    d.bad_frames = bad_frames_.load(std::memory_order_relaxed);
    publish(d, stamps_[front_]);
    last_frame_ns_ = rt::monotonic_ns();
    return HookResult::kOk;
  }
  if (ended_.load(std::memory_order_acquire) != 0) return HookResult::kError;  // the file ended
  if (static_cast<double>(rt::monotonic_ns() - last_frame_ns_) > device_timeout_ms_.get_float() * 1e6) {
    return HookResult::kError;  // the source stopped delivering
  }
  return HookResult::kOk;
}

void Camera::run() noexcept {
  Capture& c = *capture_;
  const std::string format = format_.get_string();
  while (!quit_.load(std::memory_order_acquire)) {
    if (!capturing_.load(std::memory_order_acquire)) {
      if (c.video.isOpened()) c.video.release();
      rt::sleep_for(5 * rt::kNsPerMs);
      continue;
    }
    try {
      if (!c.video.isOpened()) {
        const std::string src = source_.get_string();
        const bool index = !src.empty() && std::all_of(src.begin(), src.end(), ::isdigit);
        // A path must be what it claims: a device under /dev, otherwise a regular file
        // (OpenCV would wait for ever on a FIFO, and this thread with it). Image
        // sequences (a printf pattern) and URLs are OpenCV's to open.
        std::string refused;
        if (!index && !is_pattern_or_url(src)) {
          const bool ok = src.rfind("/dev/", 0) == 0 ? rt::check_char_device(src, "camera device", refused)
                                                     : rt::check_regular_file(src, UINT64_MAX, "video file", refused);
          if (!ok) log_error("%s", refused.c_str());
        }
        const bool ok = refused.empty() && (index ? c.video.open(std::stoi(src)) : c.video.open(src));
        if (!ok) {
          open_state_.store(-1, std::memory_order_release);
          capturing_.store(false, std::memory_order_release);
          continue;
        }
        if (width_.get_int() > 0) c.video.set(cv::CAP_PROP_FRAME_WIDTH, static_cast<double>(width_.get_int()));
        if (height_.get_int() > 0) c.video.set(cv::CAP_PROP_FRAME_HEIGHT, static_cast<double>(height_.get_int()));
        if (fps_.get_float() > 0) c.video.set(cv::CAP_PROP_FPS, fps_.get_float());
        open_state_.store(1, std::memory_order_release);
      }
      const bool got = c.video.read(c.frame);
      const int64_t capture_time = rt::host_time_ns();  // after the read: when the frame was here
      if (!got || c.frame.empty()) {
        // The end of a file or sequence, or a device that stopped.
        const double pos = c.video.get(cv::CAP_PROP_POS_FRAMES);
        const double count = c.video.get(cv::CAP_PROP_FRAME_COUNT);
        if (count > 0 && pos >= count - 1 && loop_file_.get_bool()) {
          c.video.set(cv::CAP_PROP_POS_FRAMES, 0);
          if (c.video.get(cv::CAP_PROP_POS_FRAMES) != 0) c.video.release();  // cannot seek: reopen
          continue;
        }
        if (count > 0 && pos >= count - 1) {
          ended_.store(1, std::memory_order_release);
        } else {
          bad_frames_.fetch_add(1, std::memory_order_relaxed);
        }
        c.video.release();
        capturing_.store(false, std::memory_order_release);  // on() opens it again
        continue;
      }
      // Convert and fit into the payload.
      if (format == "mono") {
        if (c.frame.channels() == 3) cv::cvtColor(c.frame, c.converted, cv::COLOR_BGR2GRAY);
        else c.converted = c.frame;
      } else if (c.frame.channels() == 1) {
        cv::cvtColor(c.frame, c.converted, cv::COLOR_GRAY2RGB);
      } else {
        cv::cvtColor(c.frame, c.converted, cv::COLOR_BGR2RGB);
      }
      const std::size_t bpp = format == "mono" ? 1 : 3;
      const double fit = std::sqrt(static_cast<double>(interfaces::kCameraMaxBytes) /
                                   (static_cast<double>(c.converted.total()) * static_cast<double>(bpp)));
      const cv::Mat* img = &c.converted;
      if (fit < 1.0) {
        cv::resize(c.converted, c.scaled, cv::Size(), fit, fit, cv::INTER_AREA);
        img = &c.scaled;
      }
      CameraData& d = buffers_[static_cast<std::size_t>(c.back)];
      d.width = static_cast<uint32_t>(img->cols);
      d.height = static_cast<uint32_t>(img->rows);
      if (format == "jpeg") {
        cv::Mat bgr;
        cv::cvtColor(*img, bgr, cv::COLOR_RGB2BGR);
        cv::imencode(".jpg", bgr, c.jpeg, {cv::IMWRITE_JPEG_QUALITY, static_cast<int>(jpeg_quality_.get_int())});
        if (c.jpeg.size() > interfaces::kCameraMaxBytes) {
          bad_frames_.fetch_add(1, std::memory_order_relaxed);
          continue;
        }
        std::memcpy(d.data, c.jpeg.data(), c.jpeg.size());
        d.bytes = static_cast<uint32_t>(c.jpeg.size());
        d.format = interfaces::kCameraJpeg;
      } else {
        const std::size_t row = static_cast<std::size_t>(img->cols) * bpp;
        for (int y = 0; y < img->rows; ++y) std::memcpy(d.data + static_cast<std::size_t>(y) * row, img->ptr(y), row);
        d.bytes = static_cast<uint32_t>(row * static_cast<std::size_t>(img->rows));
        d.format = format == "mono" ? interfaces::kCameraMono8 : interfaces::kCameraRgb8;
      }
      d.calibrated = c.calibrated ? 1 : 0;
      if (c.calibrated) {
        // The camera matrix scales with the image; distortion does not.
        const double sx = static_cast<double>(d.width) / c.calib_width;
        const double sy = static_cast<double>(d.height) / c.calib_height;
        d.fx = c.fx * sx;
        d.fy = c.fy * sy;
        d.cx = c.cx * sx;
        d.cy = c.cy * sy;
        std::copy(std::begin(c.dist), std::end(c.dist), d.distortion);
      }
      d.frame = delivered_.fetch_add(1, std::memory_order_relaxed) + 1;
      stamps_[c.back] = capture_time;
      const uint8_t previous = middle_.exchange(static_cast<uint8_t>(c.back | kFresh), std::memory_order_acq_rel);
      c.back = previous & static_cast<uint8_t>(~kFresh);
      // Pace a file or sequence at the requested rate (a device paces itself).
      if (fps_.get_float() > 0 && c.video.get(cv::CAP_PROP_FRAME_COUNT) > 0) {
        rt::sleep_for(static_cast<int64_t>(1e9 / fps_.get_float()));
      }
    } catch (const std::exception&) {
      bad_frames_.fetch_add(1, std::memory_order_relaxed);
      c.video.release();
      capturing_.store(false, std::memory_order_release);
    }
  }
  if (c.video.isOpened()) c.video.release();
}

}  // namespace rack::components
