// MRPT rawlog files, read with MRPT's own deserialisation (CArchive::ReadObject over a
// gz-capable stream), in both layouts MRPT writes:
// - actions + sensory frames: each CActionRobotMovement2D is the odometry increment
//   since the previous frame; summing them gives the odometry pose at each frame;
// - observations only: CObservationOdometry carries the absolute odometry pose.
// Planar scans (CObservation2DRangeScan) become ScanRecords; other observations are
// counted as ignored. MRPT is linked privately to the replay target only.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string_view>
#include <cmath>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/datetime.h>

#include "rawlog_reader.h"

#include "rack/rt/input_file.h"

namespace rack::replay {

namespace {

// MRPT's message is long (nested frames); its first line that names the cause is kept.
std::string first_line(std::string what) {
  if (const auto m = what.find("Message:"); m != std::string::npos) what = what.substr(m + 8);
  if (const auto nl = what.find('\n'); nl != std::string::npos) what.resize(nl);
  if (const auto start = what.find_first_not_of(' '); start != std::string::npos) what = what.substr(start);
  return what.substr(0, 300);
}

// Rawlogs written without time stamps (old datasets) are replayed at this spacing,
// from this time on (replayed samples carry the log's time, which must be positive).
constexpr double kUntimedSpacing = 0.1;  // s
constexpr double kUntimedStart = 1.0;    // s

struct Builder {
  LoadLogResult& out;
  double last_time = 0.0;
  bool have_time = false;
  mrpt::poses::CPose2D odometry;  // actions layout: accumulated increments
  bool have_odometry = false;

  double time_of(const mrpt::Clock::time_point& t) {
    if (t != INVALID_TIMESTAMP) {
      last_time = mrpt::Clock::toDouble(t);
      have_time = true;
    } else {
      last_time = have_time ? last_time + kUntimedSpacing : kUntimedStart;
      have_time = true;
    }
    return last_time;
  }

  void add_scan(const mrpt::obs::CObservation2DRangeScan& o, double time, int index) {
    const std::size_t n = o.getScanSize();
    if (n < 2) {
      out.add_error(
          {out.log.source, 0, "record " + std::to_string(index) + ": 2-D scan with " + std::to_string(n) + " beams"});
      return;
    }
    ScanRecord s;
    s.time = time;
    s.line = index;
    s.max_range = o.maxRange;
    // Beam 0 at -aperture/2 counter-clockwise (rightToLeft), else at +aperture/2.
    const float step = o.aperture / static_cast<float>(n - 1);
    s.start_angle = o.rightToLeft ? -0.5F * o.aperture : 0.5F * o.aperture;
    s.angle_step = o.rightToLeft ? step : -step;
    s.ranges.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      s.ranges[i] = o.getScanRangeValidity(i) ? o.getScanRange(i) : 0.0F;
    }
    if (o.hasIntensity()) {
      s.intensities.resize(n);
      for (std::size_t i = 0; i < n; ++i) s.intensities[i] = static_cast<float>(o.getScanIntensity(i));
    }
    s.laser_x = o.sensorPose.x();
    s.laser_y = o.sensorPose.y();
    s.laser_phi = o.sensorPose.yaw();
    if (have_odometry) {
      s.has_odometry = true;
      s.odom_x = odometry.x();
      s.odom_y = odometry.y();
      s.odom_phi = odometry.phi();
    }
    out.log.scans.push_back(std::move(s));
  }

  void add_odometry(double time, int index) {
    OdometryRecord r;
    r.time = time;
    r.x = odometry.x();
    r.y = odometry.y();
    r.phi = odometry.phi();
    r.line = index;
    out.log.odometry.push_back(r);
  }

  void observation(const mrpt::obs::CObservation::Ptr& obs, int index) {
    if (!obs) return;
    if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(obs)) {
      odometry = odo->odometry;
      have_odometry = true;
      add_odometry(time_of(odo->timestamp), index);
    } else if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(obs)) {
      add_scan(*scan, time_of(scan->timestamp), index);
    } else {
      ++out.ignored;
    }
  }

  void frame(const mrpt::obs::CActionCollection::Ptr& action, const mrpt::obs::CSensoryFrame::Ptr& sf, int index) {
    if (action) {
      if (auto mv = action->getBestMovementEstimation()) {
        // A deserialised action may lack its pose PDF: then only the raw reading counts.
        if (mv->estimationMethod == mrpt::obs::CActionRobotMovement2D::emOdometry || !mv->poseChange) {
          odometry = odometry + mv->rawOdometryIncrementReading;
        } else {
          odometry = odometry + mrpt::poses::CPose2D(mv->poseChange->getMeanVal());
        }
        have_odometry = true;
      }
    }
    if (!sf || sf->size() == 0) return;
    const auto first = sf->getObservationByIndex(0);  // a file may hold a null entry
    const double t = time_of(first ? first->timestamp : INVALID_TIMESTAMP);
    if (have_odometry) add_odometry(t, index);
    for (const auto& obs : *sf) {
      if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(obs)) {
        add_scan(*scan, scan->timestamp != INVALID_TIMESTAMP ? mrpt::Clock::toDouble(scan->timestamp) : t, index);
      } else {
        ++out.ignored;
      }
    }
  }
};

// ---- isolation: MRPT's deserialisation in a child process ------------------------
//
// MRPT's readers are not total: fuzz_rawlog found a null dereference inside
// CActionRobotMovement2D::serializeFrom (SIGSEGV on 150 bytes), exit() from libjpeg,
// and allocations of whatever length a record claims. load_rawlog() (what rackd uses)
// therefore runs them in a forked child with an address-space limit and a time limit;
// the child sends its progress (record index and offset before each record) and then
// the result through a pipe; a child that dies is an error naming the record it was in.
// parse_rawlog() stays in-process for tests and the fuzz harness.

constexpr char kFrameProgress = 'P';
constexpr char kFrameResult = 'D';
constexpr uint64_t kChildAddressSpace = uint64_t{512} << 20;  // 512 MiB + 2x the data more than it inherits
constexpr int kChildSeconds = 300;                            // CPU and wall time of the child

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

void send_progress(int fd, int index, uint64_t offset) noexcept {
  char frame[1 + 4 + 8];
  frame[0] = kFrameProgress;
  const auto i = static_cast<uint32_t>(index);
  std::memcpy(frame + 1, &i, 4);
  std::memcpy(frame + 5, &offset, 8);
  (void)write_all(fd, frame, sizeof frame);
}

template <typename T>
void put(std::string& b, const T& v) {
  b.append(reinterpret_cast<const char*>(&v), sizeof v);
}
void put_floats(std::string& b, const std::vector<float>& v) {
  put(b, static_cast<uint64_t>(v.size()));
  b.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(float));
}
void put_text(std::string& b, const std::string& t) {
  put(b, static_cast<uint64_t>(t.size()));
  b += t;
}

// The child's result, in this build's own layout (the same binary reads it back).
std::string encode(const LoadLogResult& r) {
  std::string b;
  put(b, r.lines);
  put(b, r.ignored);
  put(b, r.error_count);
  put(b, static_cast<uint64_t>(r.errors.size()));
  for (const auto& e : r.errors) {
    put(b, e.line);
    put_text(b, e.message);
  }
  put(b, static_cast<uint64_t>(r.log.odometry.size()));
  for (const auto& o : r.log.odometry) put(b, o);
  put(b, static_cast<uint64_t>(r.log.scans.size()));
  for (const auto& s : r.log.scans) {
    put(b, s.time);
    put(b, s.start_angle);
    put(b, s.angle_step);
    put(b, s.max_range);
    put(b, s.has_odometry);
    put(b, s.odom_x);
    put(b, s.odom_y);
    put(b, s.odom_phi);
    put(b, s.laser_x);
    put(b, s.laser_y);
    put(b, s.laser_phi);
    put(b, s.line);
    put_floats(b, s.ranges);
    put_floats(b, s.intensities);
  }
  return b;
}

class Decoder {
 public:
  explicit Decoder(std::string_view b) : b_(b) {}
  template <typename T>
  bool get(T& v) {
    if (b_.size() - at_ < sizeof v) return false;
    std::memcpy(&v, b_.data() + at_, sizeof v);
    at_ += sizeof v;
    return true;
  }
  bool floats(std::vector<float>& v) {
    uint64_t n = 0;
    if (!get(n) || n > (b_.size() - at_) / sizeof(float)) return false;
    v.resize(static_cast<std::size_t>(n));
    std::memcpy(v.data(), b_.data() + at_, v.size() * sizeof(float));
    at_ += v.size() * sizeof(float);
    return true;
  }
  bool text(std::string& t) {
    uint64_t n = 0;
    if (!get(n) || n > b_.size() - at_) return false;
    t.assign(b_.data() + at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
    return true;
  }
  [[nodiscard]] std::size_t left() const { return b_.size() - at_; }

 private:
  std::string_view b_;
  std::size_t at_ = 0;
};

bool decode(std::string_view b, const std::string& path, LoadLogResult& r) {
  Decoder d(b);
  uint64_t n = 0;
  if (!d.get(r.lines) || !d.get(r.ignored) || !d.get(r.error_count) || !d.get(n) || n > kMaxLogErrors) return false;
  for (uint64_t i = 0; i < n; ++i) {
    LogError e{path, 0, {}};
    if (!d.get(e.line) || !d.text(e.message)) return false;
    r.errors.push_back(std::move(e));
  }
  if (!d.get(n) || n > d.left() / sizeof(OdometryRecord)) return false;
  r.log.odometry.resize(static_cast<std::size_t>(n));
  for (auto& o : r.log.odometry) {
    if (!d.get(o)) return false;
  }
  if (!d.get(n) || n > d.left()) return false;
  r.log.scans.resize(static_cast<std::size_t>(n));
  for (auto& s : r.log.scans) {
    if (!d.get(s.time) || !d.get(s.start_angle) || !d.get(s.angle_step) || !d.get(s.max_range) ||
        !d.get(s.has_odometry) || !d.get(s.odom_x) || !d.get(s.odom_y) || !d.get(s.odom_phi) || !d.get(s.laser_x) ||
        !d.get(s.laser_y) || !d.get(s.laser_phi) || !d.get(s.line) || !d.floats(s.ranges) || !d.floats(s.intensities)) {
      return false;
    }
  }
  return d.left() == 0;
}

LoadLogResult parse_rawlog_unchecked(const std::string& path, const std::string& bytes, int progress_fd,
                                     bool stop_at_images);
LoadLogResult parse_rawlog_isolated(const std::string& path, const std::string& bytes);

}  // namespace

bool gunzip_bounded(const std::string& in, uint64_t max_out, std::string& out, std::string& error) {
  out.clear();
  z_stream z{};
  // 16 + MAX_WBITS: gzip wrapper only (a zlib or raw stream is not a rawlog).
  if (inflateInit2(&z, 16 + MAX_WBITS) != Z_OK) {
    error = "cannot start zlib";
    return false;
  }
  std::size_t pos = 0;
  char chunk[65536];
  int rc = Z_OK;
  for (;;) {
    const std::size_t avail = std::min<std::size_t>(in.size() - pos, 1u << 30);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data() + pos));
    z.avail_in = static_cast<uInt>(avail);
    z.next_out = reinterpret_cast<Bytef*>(chunk);
    z.avail_out = sizeof chunk;
    rc = inflate(&z, Z_NO_FLUSH);
    pos += avail - z.avail_in;
    const std::size_t produced = sizeof chunk - z.avail_out;
    if (out.size() + produced > max_out) {
      inflateEnd(&z);
      error = "gzip data decompresses to more than the limit of " + std::to_string(max_out) +
              " bytes (at byte offset " + std::to_string(pos) + " of the file)";
      out.clear();
      return false;
    }
    out.append(chunk, produced);
    if (rc == Z_STREAM_END) {
      // Another gzip member may follow (as gzip -c a b > c writes).
      if (pos >= in.size()) break;
      if (inflateReset(&z) != Z_OK) break;
      continue;
    }
    if (rc == Z_BUF_ERROR && produced == 0 && z.avail_in == 0) {
      inflateEnd(&z);
      error = "gzip data is truncated: the file ends at byte offset " + std::to_string(pos) + " inside the stream";
      out.clear();
      return false;
    }
    if (rc != Z_OK && rc != Z_BUF_ERROR) {
      error = std::string("gzip data is corrupt at byte offset ") + std::to_string(pos) +
              " of the file: " + (z.msg != nullptr ? z.msg : "zlib error " + std::to_string(rc));
      inflateEnd(&z);
      out.clear();
      return false;
    }
  }
  inflateEnd(&z);
  return true;
}

LoadLogResult load_rawlog(const std::string& path) {
  LoadLogResult result;
  result.log.source = path;
  try {
    std::string bytes, error;
    if (!rt::read_regular_file(path, kMaxLogFileBytes, "rawlog", bytes, error)) {
      result.add_error(path_error(path, error));
      return result;
    }
    return parse_rawlog_isolated(path, bytes);
  } catch (const std::exception& e) {  // allocation within the limits failed: refused, never past here
    result = LoadLogResult{};
    result.log.source = path;
    result.add_error({path, 0, std::string("cannot load the rawlog: ") + e.what()});
    return result;
  }
}

LoadLogResult parse_rawlog(const std::string& path, const std::string& bytes) {
  try {
    return parse_rawlog_unchecked(path, bytes, -1, /*stop_at_images=*/true);
  } catch (const std::exception& e) {  // MRPT may allocate what a record claims (bad_alloc): refused here
    LoadLogResult result;
    result.log.source = path;
    result.add_error({path, 0, std::string("cannot load the rawlog: ") + first_line(e.what())});
    return result;
  }
}

namespace {

LoadLogResult parse_rawlog_unchecked(const std::string& path, const std::string& bytes, int progress_fd,
                                     bool stop_at_images) {
  LoadLogResult result;
  result.log.source = path;
  const std::string* data = &bytes;
  std::string inflated;
  if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f &&
      static_cast<unsigned char>(bytes[1]) == 0x8b) {
    std::string error;
    if (!gunzip_bounded(bytes, kMaxRawlogBytes, inflated, error)) {
      result.add_error({path, 0, error});
      return result;
    }
    data = &inflated;
  }
  // MRPT decodes a JPEG image (CImage) with libjpeg's default error handler, which
  // calls exit() on corrupt data (found by fuzz_rawlog). In this process (parse_rawlog)
  // a rawlog is read only up to the first class name holding "Image" (CImage, its old
  // alias CMRPTImage, the observations that carry images), and what follows is refused
  // with its offset; in load_rawlog's child, where an exit() ends only the child,
  // images are read.
  const std::size_t image_at = stop_at_images ? data->find("Image") : std::string::npos;
  const std::size_t usable = image_at == std::string::npos ? data->size() : image_at;
  const auto image_error = [&](int index, uint64_t offset) {
    result.add_error({path, 0,
                      "record " + std::to_string(index) + " at byte offset " + std::to_string(offset) +
                          " (uncompressed) holds an image (a class named *Image* at byte offset " +
                          std::to_string(image_at) +
                          "): rawlogs are read up to their first image (MRPT's JPEG decoder ends the "
                          "process on a corrupt one); remove the images (rawlog-edit --remove-label)"});
  };
  mrpt::io::CMemoryStream file;
  file.assignMemoryNotOwn(data->data(), usable);
  auto archive = mrpt::serialization::archiveFrom(file);
  Builder b{result, 0.0, false, mrpt::poses::CPose2D(), false};
  mrpt::obs::CActionCollection::Ptr pending_action;
  // Objects are read one by one with MRPT's deserialisation (not through
  // CRawlog::getActionObservationPairOrObservation, which prints a failure to stderr
  // and reports it as a clean end of file: a truncated rawlog would pass unnoticed).
  int index = 0;
  for (;;) {
    const uint64_t offset = file.getPosition();
    if (progress_fd >= 0) send_progress(progress_fd, index, offset);
    mrpt::serialization::CSerializable::Ptr object;
    try {
      object = archive.ReadObject();
    } catch (const mrpt::serialization::CExceptionEOF&) {
      if (file.getPosition() == offset && usable == data->size()) break;  // a clean end between two records
      if (usable != data->size()) {
        image_error(index, offset);
        break;
      }
      result.add_error({path, 0,
                        "record " + std::to_string(index) + " truncated at byte offset " + std::to_string(offset) +
                            " (uncompressed)"});
      break;
    } catch (const std::exception& e) {
      // MRPT wraps an end of data inside a nested object in its own exception: the
      // stream standing at the end says it was cut.
      if (usable != data->size() && file.getPosition() >= usable) {
        image_error(index, offset);
      } else if (file.getPosition() >= data->size()) {
        result.add_error({path, 0,
                          "record " + std::to_string(index) + " truncated at byte offset " + std::to_string(offset) +
                              " (uncompressed): the data ends inside it"});
      } else {
        result.add_error({path, 0,
                          "record " + std::to_string(index) + " at byte offset " + std::to_string(offset) +
                              " (uncompressed) is unreadable: " + first_line(e.what())});
      }
      break;
    }
    ++result.lines;
    try {
      if (auto sf = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(object)) {
        b.frame(pending_action, sf, index);
        pending_action.reset();
      } else if (auto act = std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(object)) {
        pending_action = act;  // applies to the next sensory frame
      } else if (auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object)) {
        b.observation(obs, index);
      } else {
        ++result.ignored;
      }
    } catch (const std::exception& e) {  // MRPT accessors check their own invariants
      result.add_error({path, 0,
                        "record " + std::to_string(index) + " at byte offset " + std::to_string(offset) +
                            " (uncompressed) is inconsistent: " + first_line(e.what())});
      break;
    }
    ++index;
  }
  if (result.errors.empty() && result.log.scans.empty()) {
    result.add_error({path, 0, "no 2-D laser scan in " + std::to_string(result.lines) + " rawlog entries"});
  }
  return result;
}

int exit_code(int status) noexcept { return WIFEXITED(status) ? WEXITSTATUS(status) : -1; }

LoadLogResult parse_rawlog_isolated(const std::string& path, const std::string& bytes) {
  LoadLogResult result;
  result.log.source = path;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    result.add_error({path, 0, std::string("cannot start the rawlog reader: pipe: ") + std::strerror(errno)});
    return result;
  }
  const pid_t child = ::fork();
  if (child < 0) {
    const int e = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    result.add_error({path, 0, std::string("cannot start the rawlog reader: fork: ") + std::strerror(e)});
    return result;
  }
  if (child == 0) {
    // The child: only this thread exists. A crash must not run the parent's crash
    // reporters (they would write a false report of rackd), and its memory is bounded.
    for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP}) ::signal(sig, SIG_DFL);
    ::close(fds[0]);
    // What it may map beyond what it inherited (sanitizer builds reserve terabytes of
    // shadow memory: an absolute limit would fail every allocation there).
    unsigned long long pages = 0;
    if (std::FILE* statm = std::fopen("/proc/self/statm", "r")) {
      if (std::fscanf(statm, "%llu", &pages) != 1) pages = 0;
      std::fclose(statm);
    }
    if (pages > 0) {
      const uint64_t limit = pages * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE)) + kChildAddressSpace +
                             2 * uint64_t{bytes.size()};
      const rlimit as{limit, limit};
      (void)::setrlimit(RLIMIT_AS, &as);
    }
    const rlimit cpu{kChildSeconds, kChildSeconds};
    (void)::setrlimit(RLIMIT_CPU, &cpu);
    int status = 1;
    try {
      const LoadLogResult r = parse_rawlog_unchecked(path, bytes, fds[1], /*stop_at_images=*/false);
      const std::string payload = encode(r);
      const uint64_t size = payload.size();
      const char tag = kFrameResult;
      if (write_all(fds[1], &tag, 1) && write_all(fds[1], &size, sizeof size) &&
          write_all(fds[1], payload.data(), payload.size())) {
        status = 0;
      }
    } catch (...) {
      status = 2;  // bad_alloc under RLIMIT_AS, or MRPT: the parent names the record
    }
    ::_exit(status);
  }
  ::close(fds[1]);
  // The parent: read progress frames and the result, bounded in size and time.
  std::string buf;
  const uint64_t max_bytes = kMaxRawlogBytes * 4;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kChildSeconds + 10);
  bool timed_out = false, too_big = false;
  char chunk[65536];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline -
                                                                            std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<int64_t>(left.count(), 1000)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    const ssize_t n = ::read(fds[0], chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    buf.append(chunk, static_cast<std::size_t>(n));
    if (buf.size() > max_bytes) {
      too_big = true;
      break;
    }
  }
  ::close(fds[0]);
  if (timed_out || too_big) ::kill(child, SIGKILL);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  // Frames: progress (index, offset) ..., then the result.
  uint32_t index = 0;
  uint64_t offset = 0;
  bool any_record = false;
  std::size_t at = 0;
  std::string_view payload;
  bool have_payload = false;
  while (at < buf.size()) {
    if (buf[at] == kFrameProgress && buf.size() - at >= 13) {
      std::memcpy(&index, buf.data() + at + 1, 4);
      std::memcpy(&offset, buf.data() + at + 5, 8);
      any_record = true;
      at += 13;
    } else if (buf[at] == kFrameResult && buf.size() - at >= 9) {
      uint64_t size = 0;
      std::memcpy(&size, buf.data() + at + 1, 8);
      if (size == buf.size() - at - 9) {
        payload = std::string_view(buf).substr(at + 9);
        have_payload = true;
      }
      break;
    } else {
      break;
    }
  }
  const std::string where = any_record ? "record " + std::to_string(index) + " at byte offset " +
                                             std::to_string(offset) + " (uncompressed)"
                                       : "the first record";
  if (timed_out) {
    result.add_error(
        {path, 0, where + ": the rawlog reader took more than " + std::to_string(kChildSeconds) + " s; stopped"});
  } else if (too_big) {
    result.add_error({path, 0, "the rawlog decodes to more than " + std::to_string(max_bytes) + " bytes; refused"});
  } else if (WIFSIGNALED(status)) {
    result.add_error(
        {path, 0,
         where + ": MRPT's reader crashed on it (" + strsignal(WTERMSIG(status)) + "): the data is corrupt; refused"});
  } else if (!have_payload || exit_code(status) != 0) {
    std::string why = "exit " + std::to_string(exit_code(status));
    if (exit_code(status) == 2) why = "out of memory: a record claims more than the data can hold";
    result.add_error({path, 0, where + ": MRPT's reader failed on it (" + why + "): the data is corrupt; refused"});
  } else if (!decode(payload, path, result)) {
    result = LoadLogResult{};
    result.log.source = path;
    result.add_error({path, 0, "the rawlog reader's result is malformed (internal error)"});
  }
  return result;
}

}  // namespace

}  // namespace rack::replay
