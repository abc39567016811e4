// Recorded robot data, independent of the file format it came from: odometry poses
// and planar laser scans with their times. The CARMEN reader (carmen_log.h) and the
// MRPT rawlog reader (rawlog.h) fill it; the replay components (CarmenReplay,
// LadarReplay) play it back.
//
// Times are seconds of the recording's clock (as logged); poses are in the recording's
// odometry frame. Scans are in the laser's frame: beam i points at
// start_angle + i * angle_step (counter-clockwise positive).
//
// Real-time contract: plain data; the readers that fill it are not RT-safe (files,
// allocation) and run at set-up.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rack::replay {

struct OdometryRecord {
  double time = 0.0;                   // s
  double x = 0.0, y = 0.0, phi = 0.0;  // odometry frame
  double tv = 0.0, rv = 0.0;           // m/s, rad/s as logged (0 when not)
  int line = 0;                        // source line (CARMEN) or record index (rawlog)
};

struct ScanRecord {
  double time = 0.0;               // s
  float start_angle = 0.0F;        // rad
  float angle_step = 0.0F;         // rad
  float max_range = 0.0F;          // m
  std::vector<float> ranges;       // m (<= 0 or >= max_range: no echo)
  std::vector<float> intensities;  // empty when the log has none
  // Robot odometry pose when the scan was taken, if the line carries it.
  bool has_odometry = false;
  double odom_x = 0.0, odom_y = 0.0, odom_phi = 0.0;
  // Laser pose on the robot (ROBOTLASER1 and rawlogs carry it; FLASER: zero).
  double laser_x = 0.0, laser_y = 0.0, laser_phi = 0.0;
  int line = 0;
};

struct ReplayLog {
  std::string source;                                // file name
  std::vector<OdometryRecord> odometry;              // sorted by time
  std::vector<ScanRecord> scans;                     // sorted by time
  [[nodiscard]] double first_time() const noexcept;  // earliest record (0 when empty)
  [[nodiscard]] double last_time() const noexcept;
};

// A problem with one line (or record) of a log file.
struct LogError {
  std::string file;
  int line = 0;  // 1-based line (CARMEN); 0: not about a line (rawlogs name the record in the message)
  std::string message;
  [[nodiscard]] std::string str() const;  // "file:line: message"
};
// An error of rack/rt/input_file.h ("path: ...") as a LogError of that file.
[[nodiscard]] LogError path_error(const std::string& path, const std::string& error);

// Limits of the log readers (README "Replay"): a log file is a regular file (a FIFO or
// device is refused without blocking) of at most kMaxLogFileBytes; a gzip rawlog
// decompresses to at most kMaxRawlogBytes; at most kMaxLogErrors errors are kept
// (error_count counts them all).
inline constexpr uint64_t kMaxLogFileBytes = 256u << 20;  // 256 MiB
inline constexpr uint64_t kMaxRawlogBytes = 1u << 30;     // 1 GiB uncompressed
inline constexpr std::size_t kMaxLogErrors = 100;

struct LoadLogResult {
  ReplayLog log;
  std::vector<LogError> errors;  // malformed lines, each with its line number (the first kMaxLogErrors)
  uint64_t error_count = 0;      // every malformed line (errors holds the first ones)
  uint64_t lines = 0;            // lines (records) read
  uint64_t ignored = 0;          // well-formed lines of kinds that carry no odometry or laser
  [[nodiscard]] bool ok() const noexcept { return errors.empty(); }
  // Records an error: kept while fewer than kMaxLogErrors are, always counted.
  void add_error(LogError e);
  [[nodiscard]] std::string error_text(std::size_t max_errors = 10) const;
};

// Reads a CARMEN log or an MRPT rawlog, chosen by its extension (.rawlog: MRPT,
// otherwise CARMEN). Never throws for bad input; an unreadable file is one error.
[[nodiscard]] LoadLogResult load_replay_log(const std::string& path);

}  // namespace rack::replay
