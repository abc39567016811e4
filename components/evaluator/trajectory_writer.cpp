#include "evaluator/trajectory_writer.h"

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "common/pose2d.h"
#include "rack/interfaces/robot.h"
#include "rack/rt/input_file.h"

namespace rack::components {

using interfaces::MclData;
using interfaces::PositionData;

namespace {
constexpr double kSameTime = 1e-6;  // s: an estimate this close to a reference pose is at its time
}  // namespace

TrajectoryError trajectory_error(const std::vector<TimedPose>& estimate, const std::vector<TimedPose>& reference,
                                 double lost_threshold, double max_gap) {
  TrajectoryError e;
  e.reference = reference.size();
  double sum_sq = 0.0, sum_sq_rot = 0.0;
  for (const TimedPose& r : reference) {
    // The first estimate at or after r.t.
    const auto after = std::lower_bound(estimate.begin(), estimate.end(), r.t - kSameTime,
                                        [](const TimedPose& p, double t) { return p.t < t; });
    TimedPose at;
    if (after != estimate.end() && after->t <= r.t + kSameTime) {
      at = *after;
    } else if (after != estimate.end() && after != estimate.begin() && after->t - (after - 1)->t <= max_gap) {
      const TimedPose& a = *(after - 1);
      const TimedPose& b = *after;
      const double f = (r.t - a.t) / (b.t - a.t);
      at = {r.t, a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.phi + f * normalize_angle(b.phi - a.phi)};
    } else {
      continue;  // unmatched
    }
    const double d = std::hypot(at.x - r.x, at.y - r.y);
    const double rot = normalize_angle(at.phi - r.phi);
    ++e.matched;
    if (d > lost_threshold) ++e.lost;
    e.max_error = std::max(e.max_error, d);
    sum_sq += d * d;
    sum_sq_rot += rot * rot;
  }
  if (e.matched > 0) {
    e.ate_rmse = std::sqrt(sum_sq / static_cast<double>(e.matched));
    e.rotation_rmse = std::sqrt(sum_sq_rot / static_cast<double>(e.matched));
  }
  return e;
}

std::vector<TimedPose> parse_trajectory_text(std::string_view text, const std::string& name) {
  std::vector<TimedPose> poses;
  int number = 0;
  while (!text.empty()) {
    const auto eol = text.find('\n');
    std::string line(text.substr(0, eol));
    text = eol == std::string_view::npos ? std::string_view() : text.substr(eol + 1);
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();  // CRLF files
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ls(line);
    std::string word;
    if (!(ls >> word)) continue;  // blank
    const std::string where = name + ":" + std::to_string(number) + ": ";
    TimedPose p;
    double* fields[4] = {&p.t, &p.x, &p.y, &p.phi};
    for (int k = 0; k < 4; ++k) {
      if (k > 0 && !(ls >> word))
        throw std::runtime_error(where + "expected 't x y theta', found " + std::to_string(k) + " field(s)");
      char* end = nullptr;
      errno = 0;
      *fields[k] = std::strtod(word.c_str(), &end);
      if (end == word.c_str() || *end != '\0') throw std::runtime_error(where + "'" + word + "' is not a number");
      if (!std::isfinite(*fields[k])) throw std::runtime_error(where + "'" + word + "' is not finite");
    }
    if (!poses.empty() && p.t < poses.back().t) {
      throw std::runtime_error(where + "time " + std::to_string(p.t) + " goes backwards");
    }
    poses.push_back(p);
  }
  return poses;
}

std::vector<TimedPose> read_trajectory_file(const std::string& path) {
  // A regular file of bounded size (rack/rt/input_file.h): an ifstream waited for ever
  // on a FIFO with no writer and read /dev/zero until memory ran out.
  std::string text, error;
  if (!rt::read_regular_file(path, kMaxTrajectoryFileBytes, "trajectory file", text, error)) {
    throw std::runtime_error(error);
  }
  return parse_trajectory_text(text, path);
}

TrajectoryWriter::TrajectoryWriter()
    : DataComponent(DataTaskMode::kTriggered),
      // Its ERROR or silence ends the input (the trajectory is complete): no failure.
      source_(declare_input<MclData, PositionData>("source", {.doc = "the MCL (or Position) whose estimates to write",
                                                              .watched = false,
                                                              .fail_on_error = false})),
      file_(declare_string(
          "file", "",
          {.doc = "output file: one 't x y theta' line per estimate (relative: to the host file's folder)",
           .required = true,
           .path = PathRole::kOutput})),
      reference_(declare_string("reference", "",
                                {.doc = "reference 't x y theta' file to compare with at the end (empty: none)",
                                 .path = PathRole::kInput})),
      lost_threshold_(declare_float(
          "lost_threshold", 0.5,
          {.doc = "m, a reference pose estimated further off than this is lost", .min = 0.0, .max = 1000.0})),
      max_gap_ms_(declare_float("max_gap_ms", 1000.0,
                                {.doc = "ms, longest gap between two estimates interpolated at a reference time",
                                 .min = 0.0,
                                 .max = 600000.0,
                                 .unit = "ms"})),
      exit_when_done_(declare_bool(
          "exit_when_done", false,
          {.doc = "stop rackd (SIGTERM to its process) when the input has ended and the error is printed"})) {}

TrajectoryWriter::~TrajectoryWriter() {
  if (out_ != nullptr) std::fclose(out_);
}

void TrajectoryWriter::init() {
  const std::string reference = reference_.get_string();
  if (!reference.empty()) {
    reference_poses_ = read_trajectory_file(reference);
    if (reference_poses_.empty()) throw std::runtime_error(reference + ": no poses");
  }
  const std::string path = file_.get_string();
  // Opening a FIFO for writing waits for a reader: rackd stalled in init().
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISFIFO(st.st_mode)) {
    throw std::runtime_error(path + ": the trajectory output is a FIFO, not a regular file");
  }
  out_ = std::fopen(path.c_str(), "w");
  if (out_ == nullptr) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
  std::fprintf(out_, "# t x y theta (s, m, m, rad): estimates of %s\n",
               source_.source_parameter().get_string().c_str());
  poses_.reserve(1 << 16);
}

void TrajectoryWriter::off() {  // the source is unsubscribed after it (declared input)
  if (out_ != nullptr) std::fflush(out_);
}

void TrajectoryWriter::cleanup() {
  if (out_ != nullptr) {
    std::fclose(out_);
    out_ = nullptr;
  }
}

void TrajectoryWriter::take() noexcept {
  TimedPose p;
  if (source_.holds<MclData>()) {
    const MclData& d = source_.value<MclData>();
    p = {static_cast<double>(d.scan_time_ns != 0 ? d.scan_time_ns : source_.time_ns()) * 1e-9, d.x, d.y, d.phi};
  } else {
    const PositionData& d = source_.value<PositionData>();
    p = {static_cast<double>(source_.time_ns()) * 1e-9, d.x, d.y, d.phi};
  }
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.phi)) return;
  if (!poses_.empty() && p.t <= poses_.back().t) return;  // not newer: written already
  if (!poses_.empty()) data_.distance += std::hypot(p.x - poses_.back().x, p.y - poses_.back().y);
  poses_.push_back(p);
  if (out_ != nullptr) std::fprintf(out_, "%.6f %.6f %.6f %.6f\n", p.t, p.x, p.y, p.phi);
}

void TrajectoryWriter::finish() noexcept {
  finished_ = true;
  if (out_ != nullptr) std::fflush(out_);
  char line[512];
  if (reference_poses_.empty()) {
    std::snprintf(line, sizeof line, "%zu poses written to %s (no reference given)", poses_.size(),
                  file_.get_string().c_str());
    log_info("%zu poses written to %s (no reference given)", poses_.size(), file_.get_string());
  } else {
    const TrajectoryError e = trajectory_error(poses_, reference_poses_, lost_threshold_.get_float(),
                                               max_gap_ms_.get_float() * 1e-3);
    data_.mcl_rms = e.ate_rmse;
    data_.mcl_max = e.max_error;
    data_.mcl_heading_rms = e.rotation_rmse;
    data_.unmatched = e.reference - e.matched;
    data_.lost = e.lost;
    std::snprintf(line, sizeof line,
                  "%zu poses written to %s; against %s: ATE RMSE %.3f m, rotation RMSE %.2f deg, lost %zu of %zu "
                  "reference poses (> %.2f m), max error %.3f m, %zu unmatched",
                  poses_.size(), file_.get_string().c_str(), reference_.get_string().c_str(), e.ate_rmse,
                  e.rotation_rmse * 180.0 / std::numbers::pi, e.lost, e.reference, lost_threshold_.get_float(),
                  e.max_error, e.reference - e.matched);
    // The same words through GDOS, as arguments (a record holds each string whole up
    // to gdos::kMaxStringBytes; one preformatted line of two paths might not fit).
    log_info(
        "%zu poses written to %s; against %s: ATE RMSE %.3f m, rotation RMSE %.2f deg, lost %zu of %zu reference "
        "poses (> %.2f m), max error %.3f m, %zu unmatched",
        poses_.size(), file_.get_string(), reference_.get_string(), e.ate_rmse,
        e.rotation_rmse * 180.0 / std::numbers::pi, e.lost, e.reference, lost_threshold_.get_float(), e.max_error,
        e.reference - e.matched);
  }
  {
    rt::PiLock lock(summary_mutex_);
    summary_ = line;
  }
  if (!poses_.empty()) publish(data_, static_cast<int64_t>(std::llround(poses_.back().t * 1e9)));
  if (exit_when_done_.get_bool()) ::kill(::getpid(), SIGTERM);  // rackd stops as on `kill`
}

HookResult TrajectoryWriter::loop() {
  const Received r = receive([&](const InputPort&) { take(); });
  const bool got = r.samples > 0;
  const bool ended = r.errors > 0;        // the source left ENABLED: the input has ended
  if (finished_) return HookResult::kOk;  // done; stays ENABLED and quiet
  if (got && !poses_.empty()) {
    if (out_ != nullptr) std::fflush(out_);
    data_.mcl_samples = poses_.size();
    const TimedPose& last = poses_.back();
    // Stamped with the estimate's time: a paced replay waits for it.
    publish(data_, static_cast<int64_t>(std::llround(last.t * 1e9)));
    rt::PiLock lock(summary_mutex_);
    summary_ = std::to_string(poses_.size()) + " poses written to " + file_.get_string();
  }
  // The end of the input: its source left ENABLED, ended its stream (a replay at the
  // end of its log), or fell silent.
  const bool silent = rt::monotonic_ns() - source_.received_ns() >= silence_ns();
  if (ended || inputs_ended() || (!got && !poses_.empty() && silent)) finish();
  return HookResult::kOk;
}

void TrajectoryWriter::describe_status(std::string& out) const {
  rt::PiLock lock(summary_mutex_);
  out += summary_;
}

}  // namespace rack::components
