#include "rack/replay/carmen_log.h"

#include "rack/rt/input_file.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

namespace rack::replay {

namespace {

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    if (i >= line.size()) break;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    out.push_back(line.substr(start, i - start));
  }
  return out;
}

// Reads fields in order; the first failure keeps its reason and stops the rest.
class Fields {
 public:
  Fields(const std::vector<std::string_view>& f, std::string_view kind) : f_(f), kind_(kind) {}

  bool number(double& out, const char* what) {
    if (!error_.empty()) return false;
    if (pos_ >= f_.size()) return fail(std::string("missing ") + what + " (field " + std::to_string(pos_ + 1) + ")");
    const std::string_view t = f_[pos_];
    const auto r = std::from_chars(t.data(), t.data() + t.size(), out);
    if (r.ec != std::errc{} || r.ptr != t.data() + t.size()) {
      return fail(std::string(what) + " is not a number: '" + std::string(t) + "' (field " + std::to_string(pos_ + 1) +
                  ")");
    }
    if (!std::isfinite(out)) {
      return fail(std::string(what) + " is not finite: '" + std::string(t) + "' (field " + std::to_string(pos_ + 1) +
                  ")");
    }
    ++pos_;
    return true;
  }
  // A number stored as float: beyond float's range is refused (the conversion would
  // be undefined, and the value inf).
  bool real(float& out, const char* what) {
    double v = 0;
    if (!number(v, what)) return false;
    if (std::fabs(v) > static_cast<double>(std::numeric_limits<float>::max())) {
      --pos_;
      return fail(std::string(what) + " is out of range: '" + std::string(f_[pos_]).substr(0, 40) + "' (field " +
                  std::to_string(pos_ + 1) + ")");
    }
    out = static_cast<float>(v);
    return true;
  }
  bool count(std::size_t& out, const char* what, std::size_t max) {
    double v = 0;
    if (!number(v, what)) return false;
    if (v < 0 || v != std::floor(v) || v > static_cast<double>(max)) {
      --pos_;
      return fail(std::string(what) + " must be a count 0.." + std::to_string(max) + ", got '" + std::string(f_[pos_]) +
                  "' (field " + std::to_string(pos_ + 1) + ")");
    }
    out = static_cast<std::size_t>(v);
    return true;
  }
  bool word(const char* what) {
    if (!error_.empty()) return false;
    if (pos_ >= f_.size()) return fail(std::string("missing ") + what + " (field " + std::to_string(pos_ + 1) + ")");
    ++pos_;
    return true;
  }
  // Enough fields left for `n` numbers? (A short line says so before the numbers fail.)
  bool need(std::size_t n, const char* what) {
    if (!error_.empty()) return false;
    if (f_.size() - pos_ < n) {
      return fail("line ends inside " + std::string(what) + ": " + std::to_string(f_.size() - pos_) + " fields left, " +
                  std::to_string(n) + " needed");
    }
    return true;
  }
  bool finish() {
    if (!error_.empty()) return false;
    if (pos_ != f_.size()) {
      return fail(std::to_string(f_.size() - pos_) + " extra field(s) after the logger timestamp, starting '" +
                  std::string(f_[pos_]) + "'");
    }
    return true;
  }
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] std::string reason() const { return std::string(kind_) + ": " + error_; }

 private:
  bool fail(std::string why) {
    error_ = std::move(why);
    return false;
  }
  const std::vector<std::string_view>& f_;
  std::string_view kind_;
  std::size_t pos_ = 1;  // field 0 is the message kind
  std::string error_;
};

constexpr std::size_t kMaxBeams = 100000;

CarmenLine parse_odom(const std::vector<std::string_view>& f, int line) {
  Fields r(f, "ODOM");
  OdometryRecord o;
  o.line = line;
  double accel = 0, logger = 0;
  r.number(o.x, "x") && r.number(o.y, "y") && r.number(o.phi, "theta") && r.number(o.tv, "tv") &&
      r.number(o.rv, "rv") && r.number(accel, "accel") && r.number(o.time, "ipc_timestamp") && r.word("ipc_hostname") &&
      r.number(logger, "logger_timestamp") && r.finish();
  if (!r.ok()) return CarmenMalformed{r.reason()};
  return o;
}

CarmenLine parse_flaser(const std::vector<std::string_view>& f, int line, const CarmenParseOptions& opt) {
  Fields r(f, "FLASER");
  ScanRecord s;
  s.line = line;
  std::size_t n = 0;
  if (!r.count(n, "num_readings", kMaxBeams)) return CarmenMalformed{r.reason()};
  if (n < 2) return CarmenMalformed{"FLASER: num_readings must be at least 2, got " + std::to_string(n)};
  if (r.need(n, "the range readings")) {
    s.ranges.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (!r.real(s.ranges[i], "range reading")) break;
    }
    double x = 0, y = 0, th = 0, logger = 0;
    r.number(x, "x") && r.number(y, "y") && r.number(th, "theta") && r.number(s.odom_x, "odom_x") &&
        r.number(s.odom_y, "odom_y") && r.number(s.odom_phi, "odom_theta") && r.number(s.time, "ipc_timestamp") &&
        r.word("ipc_hostname") && r.number(logger, "logger_timestamp") && r.finish();
  }
  if (!r.ok()) return CarmenMalformed{r.reason()};
  s.has_odometry = true;
  s.start_angle = static_cast<float>(-std::numbers::pi / 2);
  s.angle_step = static_cast<float>(std::numbers::pi / static_cast<double>(n - 1));
  s.max_range = opt.flaser_max_range;
  return s;
}

CarmenLine parse_robotlaser(const std::vector<std::string_view>& f, int line) {
  Fields r(f, "ROBOTLASER1");
  ScanRecord s;
  s.line = line;
  double type = 0, fov = 0, acc = 0, rem_mode = 0;
  float start = 0, res = 0, maxr = 0;
  std::size_t n = 0, m = 0;
  if (r.number(type, "laser_type") && r.real(start, "start_angle") && r.number(fov, "field_of_view") &&
      r.real(res, "angular_resolution") && r.real(maxr, "maximum_range") && r.number(acc, "accuracy") &&
      r.number(rem_mode, "remission_mode") && r.count(n, "num_readings", kMaxBeams) &&
      r.need(n, "the range readings")) {
    s.ranges.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (!r.real(s.ranges[i], "range reading")) break;
    }
    if (r.count(m, "num_remissions", kMaxBeams) && r.need(m, "the remission values")) {
      s.intensities.resize(m);
      for (std::size_t i = 0; i < m; ++i) {
        if (!r.real(s.intensities[i], "remission value")) break;
      }
    }
    double lx = 0, ly = 0, lth = 0, tv = 0, rv = 0, fs = 0, ss = 0, ta = 0, logger = 0;
    r.number(lx, "laser_pose_x") && r.number(ly, "laser_pose_y") && r.number(lth, "laser_pose_theta") &&
        r.number(s.odom_x, "robot_pose_x") && r.number(s.odom_y, "robot_pose_y") &&
        r.number(s.odom_phi, "robot_pose_theta") && r.number(tv, "laser_tv") && r.number(rv, "laser_rv") &&
        r.number(fs, "forward_safety_dist") && r.number(ss, "side_safety_dist") && r.number(ta, "turn_axis") &&
        r.number(s.time, "ipc_timestamp") && r.word("ipc_hostname") && r.number(logger, "logger_timestamp") &&
        r.finish();
    if (r.ok()) {
      // Mounting: the laser pose expressed in the robot pose's frame.
      const double dx = lx - s.odom_x, dy = ly - s.odom_y;
      const double c = std::cos(s.odom_phi), sn = std::sin(s.odom_phi);
      s.laser_x = c * dx + sn * dy;
      s.laser_y = -sn * dx + c * dy;
      s.laser_phi = std::remainder(lth - s.odom_phi, 2 * std::numbers::pi);
    }
  }
  if (!r.ok()) return CarmenMalformed{r.reason()};
  if (!(maxr > 0)) return CarmenMalformed{"ROBOTLASER1: maximum_range must be positive, got " + std::to_string(maxr)};
  if (n >= 2 && !(std::fabs(res) > 0)) return CarmenMalformed{"ROBOTLASER1: angular_resolution must not be 0"};
  if (m != 0 && m != n) {
    return CarmenMalformed{"ROBOTLASER1: " + std::to_string(m) + " remission values for " + std::to_string(n) +
                           " range readings (must be 0 or equal)"};
  }
  s.has_odometry = true;
  s.start_angle = start;
  s.angle_step = res;
  s.max_range = maxr;
  return s;
}

}  // namespace

CarmenLine parse_carmen_line(std::string_view line, int line_number, const CarmenParseOptions& options) {
  const auto f = split(line);
  if (f.empty() || f[0].starts_with("#")) return CarmenIgnored{};
  if (f[0] == "ODOM") return parse_odom(f, line_number);
  if (f[0] == "FLASER") return parse_flaser(f, line_number, options);
  if (f[0] == "ROBOTLASER1") return parse_robotlaser(f, line_number);
  // A message kind we do not use. It must at least look like one (an upper-case
  // word), so that a binary or garbled file is not silently "ignored" line by line.
  for (char c : f[0]) {
    if (!(std::isupper(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) || c == '_')) {
      return CarmenMalformed{"not a CARMEN message: the line starts with '" + std::string(f[0].substr(0, 40)) + "'"};
    }
  }
  return CarmenIgnored{};
}

LoadLogResult parse_carmen_text(std::string_view text, const std::string& name, const CarmenParseOptions& options) {
  LoadLogResult result;
  result.log.source = name;
  int line_number = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    ++result.lines;
    CarmenLine parsed = parse_carmen_line(line, line_number, options);
    if (auto* o = std::get_if<OdometryRecord>(&parsed)) {
      result.log.odometry.push_back(*o);
    } else if (auto* s = std::get_if<ScanRecord>(&parsed)) {
      result.log.scans.push_back(std::move(*s));
    } else if (auto* e = std::get_if<CarmenMalformed>(&parsed)) {
      result.add_error({name, line_number, e->reason});
    } else if (!split(line).empty() && !split(line)[0].starts_with("#")) {
      ++result.ignored;
    }
  }
  // Logs are written in arrival order; data times may be slightly out of order
  // between sensors. Stable: equal times keep the file's order.
  std::stable_sort(result.log.odometry.begin(), result.log.odometry.end(),
                   [](const auto& a, const auto& b) { return a.time < b.time; });
  std::stable_sort(result.log.scans.begin(), result.log.scans.end(),
                   [](const auto& a, const auto& b) { return a.time < b.time; });
  if (result.errors.empty() && result.log.odometry.empty() && result.log.scans.empty()) {
    result.add_error({name, 0,
                      "no ODOM, FLASER or ROBOTLASER1 line in " + std::to_string(result.lines) +
                          " lines: not a CARMEN log, or an empty one"});
  }
  return result;
}

LoadLogResult load_carmen_log(const std::string& path, const CarmenParseOptions& options) {
  LoadLogResult r;
  r.log.source = path;
  try {
    std::string text, error;
    if (!rt::read_regular_file(path, kMaxLogFileBytes, "log file", text, error)) {
      r.add_error(path_error(path, error));
      return r;
    }
    return parse_carmen_text(text, path, options);
  } catch (const std::exception& e) {  // allocation within the limits failed: refused, never past here
    r = LoadLogResult{};
    r.log.source = path;
    r.add_error({path, 0, std::string("cannot load the log: ") + e.what()});
    return r;
  }
}

LogError path_error(const std::string& path, const std::string& error) {
  const std::string prefix = path + ": ";
  return {path, 0, error.rfind(prefix, 0) == 0 ? error.substr(prefix.size()) : error};
}

void LoadLogResult::add_error(LogError e) {
  ++error_count;
  if (errors.size() < kMaxLogErrors) errors.push_back(std::move(e));
}

double ReplayLog::first_time() const noexcept {
  double t = 0;
  bool any = false;
  if (!odometry.empty()) {
    t = odometry.front().time;
    any = true;
  }
  if (!scans.empty() && (!any || scans.front().time < t)) t = scans.front().time;
  return t;
}

double ReplayLog::last_time() const noexcept {
  double t = 0;
  if (!odometry.empty()) t = odometry.back().time;
  if (!scans.empty() && scans.back().time > t) t = scans.back().time;
  return t;
}

std::string LogError::str() const {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + message;
  return file + ": " + message;
}

std::string LoadLogResult::error_text(std::size_t max_errors) const {
  std::string out;
  for (std::size_t i = 0; i < errors.size() && i < max_errors; ++i) {
    if (!out.empty()) out += "\n";
    out += errors[i].str();
  }
  const uint64_t shown = std::min<uint64_t>(errors.size(), max_errors);
  const uint64_t total = std::max<uint64_t>(error_count, errors.size());
  if (total > shown) out += "\n(" + std::to_string(total - shown) + " more)";
  return out;
}

}  // namespace rack::replay
