// MRPT rawlog files, read with MRPT's own deserialisation (CArchive::ReadObject over a
// gz-capable stream), in both layouts MRPT writes:
// - actions + sensory frames: each CActionRobotMovement2D is the odometry increment
//   since the previous frame; summing them gives the odometry pose at each frame;
// - observations only: CObservationOdometry carries the absolute odometry pose.
// Planar scans (CObservation2DRangeScan) become ScanRecords; other observations are
// counted as ignored. MRPT is linked privately to the replay target only.
#include <cmath>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/datetime.h>

#include "rawlog_reader.h"

namespace rack::replay {

namespace {

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
      out.errors.push_back({out.log.source, 0, "record " + std::to_string(index) + ": 2-D scan with " +
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
        const mrpt::poses::CPose2D incr =
            mv->estimationMethod == mrpt::obs::CActionRobotMovement2D::emOdometry
                ? mv->rawOdometryIncrementReading
                : mrpt::poses::CPose2D(mv->poseChange->getMeanVal());
        odometry = odometry + incr;
        have_odometry = true;
      }
    }
    if (!sf || sf->size() == 0) return;
    const double t = time_of(sf->getObservationByIndex(0)->timestamp);
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

}  // namespace

LoadLogResult load_rawlog(const std::string& path) {
  LoadLogResult result;
  result.log.source = path;
  mrpt::io::CFileGZInputStream file;
  bool opened = false;
  try {
    opened = file.open(path);
  } catch (const std::exception& e) {
    result.errors.push_back({path, 0, std::string("cannot open the rawlog: ") + e.what()});
    return result;
  }
  if (!opened) {
    result.errors.push_back({path, 0, "cannot open the rawlog"});
    return result;
  }
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
      if (file.getPosition() == offset) break;  // a clean end between two records
      result.errors.push_back({path, 0, "record " + std::to_string(index) + " truncated at byte offset " +
                                            std::to_string(offset) + " (uncompressed)"});
      break;
    } catch (const std::exception& e) {
      // MRPT's message is long (nested frames); its first line that names the cause is kept.
      std::string what = e.what();
      if (const auto m = what.find("Message:"); m != std::string::npos) what = what.substr(m + 8);
      if (const auto nl = what.find('\n'); nl != std::string::npos) what.resize(nl);
      if (const auto start = what.find_first_not_of(' '); start != std::string::npos) what = what.substr(start);
      result.errors.push_back({path, 0, "record " + std::to_string(index) + " at byte offset " +
                                            std::to_string(offset) + " (uncompressed) is unreadable: " + what});
      break;
    }
    ++result.lines;
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
    ++index;
  }
  if (result.errors.empty() && result.log.scans.empty()) {
    result.errors.push_back({path, 0, "no 2-D laser scan in " + std::to_string(result.lines) + " rawlog entries"});
  }
  return result;
}

}  // namespace rack::replay
