// CARMEN log files (carmen.sourceforge.net, "logger" format), plain C++: one message
// per line, whitespace-separated, '#' starts a comment. Lines read:
//
//   ODOM x y theta tv rv accel ipc_timestamp ipc_hostname logger_timestamp
//   FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta ipc_timestamp ipc_hostname logger_timestamp
//   ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode
//               n r_1 .. r_n m rem_1 .. rem_m laser_x laser_y laser_theta robot_x robot_y
//               robot_theta tv rv forward_safety side_safety turn_axis ipc_timestamp
//               ipc_hostname logger_timestamp
//
// FLASER is the old front laser message: 180 degrees, beams from -90 to +90 degrees,
// evenly spaced (step pi / (n - 1)), max range taken from `flaser_max_range`. Its
// x y theta is the corrected laser pose, odom_* the robot's odometry. ROBOTLASER1 gives
// the geometry itself; the laser's mounting is laser_pose minus robot_pose.
// Data times are the ipc_timestamp (when the data was taken).
//
// Other message kinds (PARAM, SYNC, TRUEPOS, RLASER, NMEA...) are well-formed but not
// used: counted as ignored. A line of a used kind with a wrong field count, a field
// that is not a number, a count that does not match, or a non-finite value is
// rejected with its line number and the reason.
//
// Real-time contract: not RT-safe (set-up only: parsing allocates).
#pragma once

#include <string>
#include <string_view>
#include <variant>

#include "rack/replay/replay_log.h"

namespace rack::replay {

struct CarmenParseOptions {
  float flaser_max_range = 81.9F;  // m: FLASER lines carry none (SICK LMS 2xx: 81.91 m)
};

// One parsed line: odometry, a scan, nothing used (comment, blank, other kind), or an
// error text (the reason, without file or line).
struct CarmenIgnored {};
struct CarmenMalformed {
  std::string reason;
};
using CarmenLine = std::variant<OdometryRecord, ScanRecord, CarmenIgnored, CarmenMalformed>;

// Parses one line (without its newline). `line_number` is stored in the record.
[[nodiscard]] CarmenLine parse_carmen_line(std::string_view line, int line_number,
                                           const CarmenParseOptions& options = {});

// Parses a whole log from memory; `name` is used in errors.
[[nodiscard]] LoadLogResult parse_carmen_text(std::string_view text, const std::string& name,
                                              const CarmenParseOptions& options = {});
// Reads and parses a file.
[[nodiscard]] LoadLogResult load_carmen_log(const std::string& path, const CarmenParseOptions& options = {});

}  // namespace rack::replay
