// A camera's calibration file as OpenCV writes it (cv::FileStorage: YAML, XML or JSON
// with camera_matrix, distortion_coefficients, image_width and image_height, the format
// of OpenCV's calibration sample), read by Camera and ObjRecogCamera (`calibration`).
// A plain decoder of the file's bytes, so that tests/fuzz/fuzz_calibration.cpp drives it.
//
// Real-time contract: NOT RT-safe (OpenCV allocates; file I/O). Set-up (init()) only.
// Both functions throw std::runtime_error "calibration 'FILE': why" (the key, the values).
#pragma once

#include <string>
#include <string_view>

namespace rack::components {

struct CameraIntrinsics {
  bool valid = false;
  int width = 0, height = 0;  // the image size they are for
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double distortion[5] = {};  // k1 k2 p1 p2 k3
  int distortion_count = 0;   // 0 (none given: no distortion), 4 or 5
};

// The calibration in `text`, the bytes of the file `name` (named in errors).
[[nodiscard]] CameraIntrinsics parse_camera_calibration(std::string_view text, const std::string& name);

// The same, in a forked child process: OpenCV's FileStorage parsers are not total (a
// SEGV inside its XML reader on a truncated header, found by fuzz_calibration), so a file
// that crashes or exhausts them ends only the child, and this throws saying so. What
// rackd uses (load_camera_calibration) and what the fuzz harness drives.
[[nodiscard]] CameraIntrinsics parse_camera_calibration_isolated(std::string_view text, const std::string& name);

// Reads the file (a regular file of at most 16 MiB: a FIFO would block OpenCV for
// ever) and parses it in a child process (parse_camera_calibration_isolated).
[[nodiscard]] CameraIntrinsics load_camera_calibration(const std::string& path);

}  // namespace rack::components
