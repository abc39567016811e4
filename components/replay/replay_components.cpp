#include "replay_components.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <numbers>
#include <stdexcept>

#include "src/shared_log.h"

namespace rack::components {

using interfaces::ChassisData;
using interfaces::LadarData;

namespace {
// At most this many records per cycle: a long stall (or a high speed) must not turn
// one cycle into an unbounded burst.
constexpr std::size_t kMaxPerCycle = 64;
// A component that joins the clock within this long of its start plays the log from
// its beginning (components of one host are switched on one after the other); one that
// joins later skips what has already played, as a live sensor would.
constexpr int64_t kJoinWindowNs = 2 * rt::kNsPerSec;

// Index of the first record to play when joining the clock at `now`.
template <typename Records>
std::size_t join_index(const replay::SharedLog& log, const Records& records, std::size_t next, int64_t now,
                       int64_t anchor, int64_t period) noexcept {
  if (next == 0 && now - anchor < kJoinWindowNs) return 0;
  while (next < records.size() && log.host_time(records[next].time) < now - period) ++next;
  return next;
}

double wrap(double a) noexcept { return std::remainder(a, 2.0 * std::numbers::pi); }

Parameter::Spec log_spec() {
  return {
      .doc = "log file to play: CARMEN (.log/.clf/...) or MRPT rawlog (.rawlog); relative: to the host file's folder",
      .required = true,
      .init_only = true,
      .path = PathRole::kInput};
}
Parameter::Spec speed_spec() {
  return {.doc = "replay speed (1: as recorded; 2: twice as fast; 0: as fast as LadarReplay's pace allows)",
          .min = 0.0,
          .max = 1000.0,
          .init_only = true};
}
constexpr std::size_t kReplyBytes = 64 * 1024;  // a data component's reply slot
Parameter::Spec strict_spec() {
  return {.doc = "a malformed line rejects the log (false: skip and report it)", .init_only = true};
}
}  // namespace

// ---------------------------------------------------------------------------
ChassisReplay::ChassisReplay()
    : DataComponent(DataTaskMode::kPeriodic),
      log_(declare_string("log", "", log_spec())),
      speed_(declare_float("speed", 1.0, speed_spec())),
      strict_(declare_bool("strict", true, strict_spec())),
      source_(declare_string("odometry", "auto",
                             {.doc = "odometry from 'odom' lines (CARMEN ODOM, rawlog odometry), 'laser' (poses on "
                                     "FLASER/ROBOTLASER1 lines, rawlog frames) or 'auto' (odom if any)",
                              .choices = {"auto", "odom", "laser"},
                              .init_only = true})) {}

ChassisReplay::~ChassisReplay() = default;

void ChassisReplay::init() {
  std::string skipped;
  shared_ = replay::acquire_shared_log(log_.get_string(), speed_.get_float(), strict_.get_bool(), skipped);
  if (!skipped.empty()) log_warning("replay: %s", skipped);
  const replay::ReplayLog& log = shared_->log();
  const std::string source = source_.get_string();  // auto, odom or laser (its Spec's choices)
  const bool use_odom = source == "odom" || (source == "auto" && !log.odometry.empty());
  if (use_odom) {
    stream_ = log.odometry;
  } else {
    for (const auto& s : log.scans) {
      if (!s.has_odometry) continue;
      stream_.push_back({s.time, s.odom_x, s.odom_y, s.odom_phi, 0.0, 0.0, s.line});
    }
  }
  if (stream_.empty()) {
    throw std::runtime_error(log.source + ": no odometry (" + (use_odom ? "no ODOM lines" : "no poses on laser lines") +
                             ")");
  }
  // Limits from what the log did (a replayed chassis cannot be driven).
  for (std::size_t i = 1; i < stream_.size(); ++i) {
    const double dt = stream_[i].time - stream_[i - 1].time;
    if (dt <= 1e-6) continue;
    const double v = std::hypot(stream_[i].x - stream_[i - 1].x, stream_[i].y - stream_[i - 1].y) / dt;
    const double w = std::fabs(wrap(stream_[i].phi - stream_[i - 1].phi)) / dt;
    params_.vx_max = std::max(params_.vx_max, v);
    params_.omega_max = std::max(params_.omega_max, w);
  }
  log_info("%zu odometry records from %s (%s), %.1f s at speed %.2f", stream_.size(), log.source,
           use_odom ? "odom" : "laser poses", stream_.back().time - stream_.front().time, speed_.get_float());
}

HookResult ChassisReplay::on() {
  joined_.store(false, std::memory_order_release);
  return HookResult::kOk;
}

HookResult ChassisReplay::loop() {
  const int64_t now = rt::host_time_ns();
  const bool paced = shared_->paced();
  if (paced && !shared_->ready()) return HookResult::kOk;  // the paced pipeline does not listen yet
  if (!joined_.exchange(true, std::memory_order_acq_rel)) {
    ended_ = false;
    const int64_t anchor = shared_->start(now);
    // Joining a running clock: records that played more than a period ago are skipped;
    // the next increment then spans them, so the integrated odometry stays right.
    // (Paced: nothing is skipped; the log waits for the pipeline.)
    if (!paced) next_ = join_index(*shared_, stream_, next_, now, anchor, period_ns());
  }
  // Paced: odometry up to the first record at or after the next scan to be released
  // (Scan2D needs it to interpolate that scan's odometry), and no further.
  double limit = std::numeric_limits<double>::infinity();
  if (paced) {
    const auto& scans = shared_->log().scans;
    const std::size_t released = shared_->scans_released();
    if (released < scans.size()) limit = scans[released].time;
  }
  const bool clocked = shared_->speed() > 0.0;
  for (std::size_t k = 0; k < kMaxPerCycle && next_ < stream_.size(); ++k) {
    const replay::OdometryRecord& r = stream_[next_];
    if (clocked && shared_->host_time(r.time) > now) break;
    if (have_last_ && last_.time >= limit) break;
    ChassisData d;
    if (have_last_) {
      const double dx = r.x - last_.x, dy = r.y - last_.y;
      const double c = std::cos(last_.phi), s = std::sin(last_.phi);
      d.delta_x = c * dx + s * dy;
      d.delta_y = -s * dx + c * dy;
      d.delta_phi = wrap(r.phi - last_.phi);
      const double dt = r.time - last_.time;
      d.vx = r.tv != 0.0 || dt <= 0 ? r.tv : d.delta_x / dt;
      d.omega = r.rv != 0.0 || dt <= 0 ? r.rv : d.delta_phi / dt;
      if (dt > 0 && r.tv == 0.0) d.vy = d.delta_y / dt;
    }
    d.active_pilot = active_pilot_.load(std::memory_order_relaxed);
    last_ = r;
    have_last_ = true;
    ++next_;
    publish(d, replay::SharedLog::sample_time(r.time));
  }
  if (next_ >= stream_.size() && !ended_) {
    ended_ = true;
    log_info("end of log: %u odometry records played from %s; no more samples (end of stream), staying ENABLED",
             static_cast<unsigned>(stream_.size()), shared_->log().source.c_str());
    end_stream();
  }
  return HookResult::kOk;
}

CommandResult ChassisReplay::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  switch (request.type) {
    case interfaces::kChassisMove:
      reply_error(request, "ChassisReplay plays a log: it cannot be driven");
      return CommandResult::kHandled;
    case interfaces::kChassisSetActivePilot: {
      interfaces::ChassisSetActivePilot p;
      if (!wire::read_payload(body, tims::body_is_native(request), p)) {
        reject_malformed(request, "SET_ACTIVE_PILOT: body must be a 4-byte address");
        return CommandResult::kHandled;
      }
      active_pilot_.store(p.pilot, std::memory_order_relaxed);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    case interfaces::kChassisGetParams:
      reply_with(request, interfaces::kChassisParamsReply, params_);
      return CommandResult::kHandled;
    default: return CommandResult::kUnknown;
  }
}

// ---------------------------------------------------------------------------
LadarReplay::LadarReplay()
    : DataComponent(DataTaskMode::kPeriodic),
      log_(declare_string("log", "", log_spec())),
      speed_(declare_float("speed", 1.0, speed_spec())),
      strict_(declare_bool("strict", true, strict_spec())),
      pace_(declare_string("pace", "",
                           {.doc = "component at the end of the pipeline (MCL, TrajectoryWriter): a scan plays only "
                                   "after it has output for the previous one (empty: the clock alone)",
                            .component_ref = true,
                            .weak_ref = true})),  // a consumer of the scans: not a dependency
      pace_timeout_ms_(declare_float("pace_timeout_ms", 2000.0,
                                     {.doc = "ms a scan waits for the paced component before it plays anyway (counted)",
                                      .min = 1.0,
                                      .max = 600000.0})) {}

LadarReplay::~LadarReplay() = default;

void LadarReplay::init() {
  std::string skipped;
  shared_ = replay::acquire_shared_log(log_.get_string(), speed_.get_float(), strict_.get_bool(), skipped);
  if (!skipped.empty()) log_warning("replay: %s", skipped);
  const replay::ReplayLog& log = shared_->log();
  if (log.scans.empty()) throw std::runtime_error(log.source + ": no laser scans");
  for (const auto& s : log.scans) {
    if (s.ranges.size() > interfaces::kLadarMaxBeams) {
      throw std::runtime_error(log.source + ":" + std::to_string(s.line) + ": scan of " +
                               std::to_string(s.ranges.size()) + " beams; a Ladar carries at most " +
                               std::to_string(interfaces::kLadarMaxBeams));
    }
  }
  out_ = std::make_unique<LadarData>();
  reply_ = std::make_unique<std::byte[]>(kReplyBytes);
  paced_ = !pace_.get_string().empty();
  if (paced_) {
    shared_->set_paced();
  } else if (!(speed_.get_float() > 0.0)) {
    throw std::runtime_error("parameter 'speed': 0 (as fast as possible) needs 'pace' (the component to wait for)");
  }
  const auto& s0 = log.scans.front();
  log_info(
      "%zu scans from %s; %zu beams from %.3f rad step %.5f rad, max %.2f m; laser at (%.3f, %.3f, %.3f) on the robot "
      "(give Scan2D this mounting)",
      log.scans.size(), log.source, s0.ranges.size(), double{s0.start_angle}, double{s0.angle_step},
      double{s0.max_range}, s0.laser_x, s0.laser_y, s0.laser_phi);
}

HookResult LadarReplay::on() {
  joined_.store(false, std::memory_order_release);
  return HookResult::kOk;
}

bool LadarReplay::pace_enabled() noexcept {
  const auto r = data_endpoint().call(resolved(pace_), tims::msg::kGetStatus,
                                      std::span<std::byte>(reply_.get(), kReplyBytes), settings().rpc_timeout_ns);
  return r.status == tims::CallStatus::kOk && r.reply.type == tims::msg::kEnabled;
}

bool LadarReplay::pace_reached(int64_t time_ns) noexcept {
  const wire::GetDataRequest newest{};  // time 0: the newest sample
  const auto r = data_endpoint().call(resolved(pace_), tims::msg::kGetData, newest,
                                      std::span<std::byte>(reply_.get(), kReplyBytes), settings().rpc_timeout_ns);
  if (r.status != tims::CallStatus::kOk || r.reply.type != tims::msg::kData ||
      r.body.size() < sizeof(wire::SampleHeader)) {
    return false;
  }
  wire::SampleHeader sh;
  if (!wire::read_payload(r.body.first(sizeof(wire::SampleHeader)), tims::body_is_native(r.reply), sh)) return false;
  return sh.time_ns >= time_ns;
}

HookResult LadarReplay::loop() {
  const int64_t now = rt::host_time_ns();
  const auto& scans = shared_->log().scans;
  const bool paced = paced_;
  if (paced && !shared_->ready()) {
    // Nothing plays before the paced component (and so everything it depends on) is
    // ENABLED and subscribed: the first records reach every consumer.
    if (!pace_enabled()) return HookResult::kOk;
    shared_->set_ready();
  }
  if (!joined_.exchange(true, std::memory_order_acq_rel)) {
    ended_ = false;
    const int64_t anchor = shared_->start(now);
    if (!paced) next_ = join_index(*shared_, scans, next_, now, anchor, period_ns());
  }
  const bool clocked = shared_->speed() > 0.0;
  for (std::size_t k = 0; k < kMaxPerCycle && next_ < scans.size(); ++k) {
    const replay::ScanRecord& s = scans[next_];
    if (clocked && shared_->host_time(s.time) > now) break;
    if (paced && next_ > 0) {
      // The paced component must have output for the previous scan first.
      if (pace_wait_since_ == 0) pace_wait_since_ = now;
      if (!pace_reached(replay::SharedLog::sample_time(scans[next_ - 1].time))) {
        if (now - pace_wait_since_ < static_cast<int64_t>(pace_timeout_ms_.get_float() * 1e6)) break;
        progress_.pace_timeouts.fetch_add(1, std::memory_order_relaxed);
      }
      pace_wait_since_ = 0;
    }
    LadarData& d = *out_;
    d.duration_ns = 0;  // logs do not say how long a sweep took
    d.max_range = s.max_range;
    d.min_range = 0.0F;
    d.start_angle = s.start_angle;
    d.angle_step = s.angle_step;
    d.beam_count = static_cast<uint32_t>(s.ranges.size());
    for (std::size_t i = 0; i < s.ranges.size(); ++i) {
      const float r = s.ranges[i];
      d.range[i] = r > 0.0F && r < s.max_range ? r : 0.0F;  // max range in a log means no echo
      d.intensity[i] = i < s.intensities.size() ? s.intensities[i] : 0.0F;
    }
    ++next_;
    const int64_t t = replay::SharedLog::sample_time(s.time);
    publish(d, t);
    // Relaxed: status counters, each read on its own.
    progress_.scans.store(next_, std::memory_order_relaxed);
    progress_.last_time_ns.store(t, std::memory_order_relaxed);
    shared_->set_scans_released(next_);
    if (paced) break;  // one scan per pace check
  }
  if (next_ >= scans.size() && !ended_) {
    ended_ = true;
    log_info("end of log: %u scans played from %s; no more samples (end of stream), staying ENABLED",
             static_cast<unsigned>(scans.size()), shared_->log().source.c_str());
    end_stream();
  }
  return HookResult::kOk;
}

void LadarReplay::describe_status(std::string& out) const {
  if (!shared_) return;
  const std::size_t total = shared_->log().scans.size();
  const uint64_t played = progress_.scans.load(std::memory_order_relaxed);
  char line[256];
  std::snprintf(line, sizeof line, "replay: %llu of %zu scans played (log time %.3f s)%s, speed %s%s",
                static_cast<unsigned long long>(played), total,
                static_cast<double>(progress_.last_time_ns.load(std::memory_order_relaxed)) * 1e-9,
                played == total ? ", log finished" : "",
                shared_->speed() > 0.0 ? std::to_string(shared_->speed()).c_str() : "0 (as fast as paced)",
                pace_.get_string().empty()
                    ? ""
                    : (", paced by " + pace_.get_string() +
                       (shared_->ready() ? ", " : " (waiting for it to be ENABLED), ") +
                       std::to_string(progress_.pace_timeouts.load(std::memory_order_relaxed)) + " pace timeout(s)")
                          .c_str());
  out += line;
}

}  // namespace rack::components
