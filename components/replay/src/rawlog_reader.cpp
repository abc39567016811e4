// MRPT rawlog files, read with MRPT's own deserialisation (CArchive::ReadObject over a
// gz-capable stream), in both layouts MRPT writes:
// - actions + sensory frames: each CActionRobotMovement2D is the odometry increment
//   since the previous frame; summing them gives the odometry pose at each frame;
// - observations only: CObservationOdometry carries the absolute odometry pose.
// Planar scans (CObservation2DRangeScan) become ScanRecords; other observations are
// counted as ignored. MRPT is linked privately to the replay target only.
#include <zlib.h>

#include <algorithm>
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

// Rawlogs written without time stamps (old datasets) are replayed at this spacing.
constexpr double kUntimedSpacing = 0.1;  // s

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
      last_time = have_time ? last_time + kUntimedSpacing : 0.0;
      have_time = true;
    }
    return last_time;
  }

  void add_scan(const mrpt::obs::CObservation2DRangeScan& o, double time, int index) {
    const std::size_t n = o.getScanSize();
    if (n < 2) {
      out.add_error({out.log.source, 0, "record " + std::to_string(index) + ": 2-D scan with " +
                                                   std::to_string(n) + " beams"});
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

  void frame(const mrpt::obs::CActionCollection::Ptr& action, const mrpt::obs::CSensoryFrame::Ptr& sf,
             int index) {
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

LoadLogResult parse_rawlog_unchecked(const std::string& path, const std::string& bytes);

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
      error = std::string("gzip data is corrupt at byte offset ") + std::to_string(pos) + " of the file: " +
              (z.msg != nullptr ? z.msg : "zlib error " + std::to_string(rc));
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
    return parse_rawlog(path, bytes);
  } catch (const std::exception& e) {  // allocation within the limits failed: refused, never past here
    result = LoadLogResult{};
    result.log.source = path;
    result.add_error({path, 0, std::string("cannot load the rawlog: ") + e.what()});
    return result;
  }
}

LoadLogResult parse_rawlog(const std::string& path, const std::string& bytes) {
  try {
    return parse_rawlog_unchecked(path, bytes);
  } catch (const std::exception& e) {  // MRPT may allocate what a record claims (bad_alloc): refused here
    LoadLogResult result;
    result.log.source = path;
    result.add_error({path, 0, std::string("cannot load the rawlog: ") + first_line(e.what())});
    return result;
  }
}

namespace {

LoadLogResult parse_rawlog_unchecked(const std::string& path, const std::string& bytes) {
  LoadLogResult result;
  result.log.source = path;
  const std::string* data = &bytes;
  std::string inflated;
  if (bytes.size() >= 2 && static_cast<unsigned char>(bytes[0]) == 0x1f && static_cast<unsigned char>(bytes[1]) == 0x8b) {
    std::string error;
    if (!gunzip_bounded(bytes, kMaxRawlogBytes, inflated, error)) {
      result.add_error({path, 0, error});
      return result;
    }
    data = &inflated;
  }
  // MRPT decodes a JPEG image (CImage) with libjpeg's default error handler, which
  // calls exit() on corrupt data (found by fuzz_rawlog): a rawlog is read only up to
  // the first class name holding "Image" (CImage, its old alias CMRPTImage, and the
  // observations that carry images), and what follows is refused with its offset.
  const std::size_t image_at = data->find("Image");
  const std::size_t usable = image_at == std::string::npos ? data->size() : image_at;
  const auto image_error = [&](int index, uint64_t offset) {
    result.add_error({path, 0, "record " + std::to_string(index) + " at byte offset " + std::to_string(offset) +
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
    mrpt::serialization::CSerializable::Ptr object;
    try {
      object = archive.ReadObject();
    } catch (const mrpt::serialization::CExceptionEOF&) {
      if (file.getPosition() == offset && usable == data->size()) break;  // a clean end between two records
      if (usable != data->size()) {
        image_error(index, offset);
        break;
      }
      result.add_error({path, 0, "record " + std::to_string(index) + " truncated at byte offset " +
                                            std::to_string(offset) + " (uncompressed)"});
      break;
    } catch (const std::exception& e) {
      // MRPT wraps an end of data inside a nested object in its own exception: the
      // stream standing at the end says it was cut.
      if (usable != data->size() && file.getPosition() >= usable) {
        image_error(index, offset);
      } else if (file.getPosition() >= data->size()) {
        result.add_error({path, 0, "record " + std::to_string(index) + " truncated at byte offset " +
                                       std::to_string(offset) + " (uncompressed): the data ends inside it"});
      } else {
        result.add_error({path, 0, "record " + std::to_string(index) + " at byte offset " + std::to_string(offset) +
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
      result.add_error({path, 0, "record " + std::to_string(index) + " at byte offset " + std::to_string(offset) +
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

}  // namespace

}  // namespace rack::replay
