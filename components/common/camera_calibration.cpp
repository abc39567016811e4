#include "common/camera_calibration.h"

#include "rack/rt/input_file.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <opencv2/core.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <type_traits>

namespace rack::components {

namespace {
// An OpenCV calibration file holds a few matrices: kilobytes.
constexpr uint64_t kMaxCalibrationBytes = 16u << 20;
// A calibration matrix is 3x3, a distortion vector at most 1x14: OpenCV allocates what a
// matrix node's rows and cols say before it reads the data (an 8 GiB malloc for a text of
// 400 bytes, found by fuzz_calibration), so they are checked first.
constexpr int kMaxMatrixSide = 16;

// Reads the matrix node `key` (absent: `m` stays empty) after checking its declared size.
// Throws std::runtime_error saying what is wrong.
void read_small_matrix(const cv::FileStorage& fs, const char* key, cv::Mat& m) {
  const cv::FileNode n = fs[key];
  if (n.empty() || n.isNone()) return;
  if (!n.isMap()) throw std::runtime_error(std::string(key) + ": not an opencv-matrix (rows, cols, dt, data)");
  if (!n["sizes"].empty())
    throw std::runtime_error(std::string(key) + ": an n-dimensional matrix, expected rows x cols");
  const cv::FileNode rows = n["rows"];
  const cv::FileNode cols = n["cols"];
  if (!rows.isInt() || !cols.isInt()) throw std::runtime_error(std::string(key) + ": rows and cols must be integers");
  const int r = static_cast<int>(rows);
  const int c = static_cast<int>(cols);
  if (r < 0 || c < 0 || r > kMaxMatrixSide || c > kMaxMatrixSide) {
    throw std::runtime_error(std::string(key) + ": " + std::to_string(r) + "x" + std::to_string(c) +
                             " is not a calibration matrix (at most " + std::to_string(kMaxMatrixSide) + " per side)");
  }
  n >> m;
}
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
      read_small_matrix(fs, "camera_matrix", km);
      read_small_matrix(fs, "distortion_coefficients", dm);
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
  if (!(k.fx > 0.0) || !(k.fy > 0.0) || !std::isfinite(k.fx) || !std::isfinite(k.fy)) {
    throw fail("camera_matrix focal lengths must be finite and > 0");
  }
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) throw fail("camera_matrix principal point must be finite");
  if (!dm.empty()) {
    dm.convertTo(dm, CV_64F);
    if (dm.total() < 4) throw fail("distortion_coefficients needs 4 or 5 values");
    k.distortion_count = static_cast<int>(std::min<std::size_t>(5, dm.total()));
    for (int i = 0; i < k.distortion_count; ++i) {
      k.distortion[i] = dm.at<double>(i);
      if (!std::isfinite(k.distortion[i])) throw fail("distortion_coefficients must be finite");
    }
  }
  k.valid = true;
  return k;
}

namespace {

bool write_all(int fd, const void* data, std::size_t n) noexcept {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

// The child's side: parse, send 'K' and the result or 'E' and the reason, exit.
[[noreturn]] void parse_in_child(std::string_view text, const std::string& name, int fd) {
  // A crash must end only this child, silently: not the parent's crash reporters (a false
  // report of rackd), not a sanitizer's report in a fuzz build.
  for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP}) ::signal(sig, SIG_DFL);
  // What it may map beyond what it inherited: a text of at most 16 MiB needs far less.
  unsigned long long pages = 0;
  if (std::FILE* statm = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(statm, "%llu", &pages) != 1) pages = 0;
    std::fclose(statm);
  }
  if (pages > 0) {
    const uint64_t limit = pages * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE)) + (uint64_t{256} << 20);
    const rlimit as{limit, limit};
    (void)::setrlimit(RLIMIT_AS, &as);
  }
  const rlimit cpu{10, 10};
  (void)::setrlimit(RLIMIT_CPU, &cpu);
  int status = 1;
  try {
    const CameraIntrinsics k = parse_camera_calibration(text, name);
    const char tag = 'K';
    if (write_all(fd, &tag, 1) && write_all(fd, &k, sizeof k)) status = 0;
  } catch (const std::exception& e) {
    const char tag = 'E';
    const std::string why = e.what();
    if (write_all(fd, &tag, 1) && write_all(fd, why.data(), std::min<std::size_t>(why.size(), 4096))) status = 0;
  } catch (...) {
    status = 2;
  }
  ::_exit(status);
}

}  // namespace

CameraIntrinsics parse_camera_calibration_isolated(std::string_view text, const std::string& name) {
  static_assert(std::is_trivially_copyable_v<CameraIntrinsics>);
  const auto fail = [&name](const std::string& why) {
    return std::runtime_error("calibration '" + name + "': " + why);
  };
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw fail(std::string("cannot start its reader: pipe: ") + std::strerror(errno));
  const pid_t child = ::fork();
  if (child < 0) {
    const int e = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw fail(std::string("cannot start its reader: fork: ") + std::strerror(e));
  }
  if (child == 0) {
    ::close(fds[0]);
    parse_in_child(text, name, fds[1]);
  }
  ::close(fds[1]);
  std::string buf;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  bool timed_out = false;
  char chunk[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<int64_t>(left, 1000)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    const ssize_t n = ::read(fds[0], chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    buf.append(chunk, static_cast<std::size_t>(n));
    if (buf.size() > 8192) break;  // more than either answer: not our child's
  }
  ::close(fds[0]);
  if (timed_out) ::kill(child, SIGKILL);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) throw fail("its reader (OpenCV) did not finish within 15 s");
  if (WIFSIGNALED(status)) {
    throw fail("OpenCV's reader crashed on it (signal " + std::to_string(WTERMSIG(status)) +
               "): not a valid OpenCV YAML, XML or JSON calibration");
  }
  if (!buf.empty() && buf[0] == 'E') throw std::runtime_error(buf.substr(1));
  if (buf.size() == 1 + sizeof(CameraIntrinsics) && buf[0] == 'K') {
    CameraIntrinsics k;
    std::memcpy(&k, buf.data() + 1, sizeof k);
    return k;
  }
  throw fail("its reader (OpenCV) failed (exit status " + std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) +
             ", out of memory or an exception)");
}

CameraIntrinsics load_camera_calibration(const std::string& path) {
  std::string text, error;
  if (!rt::read_regular_file(path, kMaxCalibrationBytes, "calibration file", text, error)) {
    throw std::runtime_error("calibration: " + error);
  }
  return parse_camera_calibration_isolated(text, path);
}

}  // namespace rack::components
