// Camera (class Camera): frames from OpenCV's VideoCapture: a V4L2 device ("/dev/video0"
// or "0"), a video file, or an image sequence ("frames/img_%04d.png").
//
// OpenCV decodes and allocates, so it never runs in an RT task: a capture thread (an
// I/O worker declared in init() and run by the executor on the housekeeping CPUs,
// capturing only while the component is ENABLED) opens the source,
// asks for the configured size and frame rate, converts each frame (RGB8, MONO8 or
// JPEG, scaled down to fit CameraData), and hands it to loop() through a lock-free
// triple buffer of preallocated CameraData. loop() (periodic, e.g. at the frame rate)
// publishes the newest frame if there is one; frames it never saw are counted as
// dropped. Calibration (camera matrix and distortion from an OpenCV calibration file,
// e.g. from opencv_interactive-calibration or calibrateCamera's FileStorage output)
// is published with every frame, scaled to the frame's size.
//
// Bad input: a source that cannot be opened, frames that fail to decode, a file that
// ends (without `loop`), or no frame for device_timeout_ms: counted, and ERROR; on() retries.
//
// Real-time contract: loop() only swaps an atomic index and publishes a preallocated
// sample; on()/off() only set atomics and wait (bounded) for the capture thread.
#pragma once

#include <atomic>
#include <memory>

#include "rack/core/data_component.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

class Camera final : public DataComponent<interfaces::CameraData> {
 public:
  Camera();
  ~Camera() override;

 protected:
  void init() override;
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT
  void cleanup() override;

 private:
  struct Capture;  // OpenCV lives in camera.cpp only
  void run() noexcept;

  Parameter& source_;
  Parameter& width_;
  Parameter& height_;
  Parameter& fps_;
  Parameter& format_;
  Parameter& jpeg_quality_;
  Parameter& loop_file_;
  Parameter& calibration_;
  Parameter& device_timeout_ms_;  // formerly timeout_ms

  std::unique_ptr<Capture> capture_;
  // Triple buffer: the capture thread fills buffers_[back], then exchanges it with
  // middle_ (acq_rel) setting kFresh; loop() exchanges its front with middle_ when
  // kFresh is set. SYNC POINT: the exchange publishes the frame's bytes.
  std::unique_ptr<interfaces::CameraData[]> buffers_;
  int64_t stamps_[3] = {};  // host-clock capture time of each buffer (travels with it)
  static constexpr uint8_t kFresh = 0x80;
  std::atomic<uint8_t> middle_{1};
  uint8_t front_ = 0;                   // loop() only
  std::atomic<bool> capturing_{false};  // on() -> thread: capture while true
  std::atomic<bool> quit_{false};
  std::atomic<int> open_state_{0};  // thread -> on(): 0 opening, 1 open, -1 failed
  std::atomic<uint32_t> bad_frames_{0}, delivered_{0}, ended_{0};
  uint32_t published_frames_ = 0;  // loop() only
  int64_t last_frame_ns_ = 0;      // loop() only
};

}  // namespace rack::components
