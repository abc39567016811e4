#include "pilot/pilot.h"

#include "path/path.h"
#include "rack/maps/occupancy_map.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <string>

namespace rack::components {

using interfaces::ChassisMove;
using interfaces::ChassisParams;
using interfaces::PathData;
using interfaces::PilotData;
using interfaces::PilotMode;
using interfaces::PilotStatus;
using interfaces::PositionData;
using interfaces::Scan2dData;

namespace {
uint8_t u8(PilotMode m) noexcept { return static_cast<uint8_t>(m); }
uint8_t u8(PilotStatus s) noexcept { return static_cast<uint8_t>(s); }
}  // namespace

Pilot::Pilot()
    : DataComponent(DataTaskMode::kPeriodic),
      chassis_(declare_component_ref("chassis", "the Chassis to drive")),
      position_(declare_input<PositionData>("position", {.doc = "the Position estimate to steer on",
                                                         .watched = false,
                                                         .silence_ms = 500.0,
                                                         .old_silence_name = "input_timeout_ms"})),
      scan2d_(
          declare_input<Scan2dData>("scan2d", {.doc = "the Scan2D whose points limit the speed", .watched = false})),
      path_(declare_input<PathData>(
          "path", {.doc = "Path to follow", .optional = true, .watched = false, .fail_on_error = false})),
      mode_(declare_string("mode", "path",
                           {.doc = "at ON: 'path' (follow the Path) or 'hold' (stand)", .choices = {"path", "hold"}})),
      destination_(
          declare_string("destination", "", {.doc = "\"x,y\": drive there (map frame); \"\": back to the mode"})),
      vx_max_(declare_float("vx_max", 0.6,
                            {.doc = "m/s, cruising speed (also capped by the chassis)", .min = 0.0, .max = 20.0})),
      omega_max_(declare_float("omega_max", 1.0,
                               {.doc = "rad/s, fastest turn (also capped by the chassis)", .min = 0.0, .max = 20.0})),
      lookahead_(
          declare_float("lookahead", 0.6, {.doc = "m, pure-pursuit look-ahead distance", .min = 0.05, .max = 20.0})),
      goal_tolerance_(declare_float(
          "goal_tolerance", 0.15, {.doc = "m, a destination this close counts as reached", .min = 0.01, .max = 10.0})),
      turn_in_place_deg_(declare_float("turn_in_place_deg", 45.0,
                                       {.doc = "turn on the spot when the goal is further off the heading",
                                        .min = 5.0,
                                        .max = 180.0,
                                        .unit = "deg"})),
      brake_fraction_(
          declare_float("brake_fraction", 0.5,
                        {.doc = "plan braking with this fraction of the chassis' dec_max", .min = 0.05, .max = 1.0})),
      map_(declare_string(
          "map", "",
          {.doc =
               "map to plan destinations on (ROS map_server YAML; relative: to the host file's folder); \"\": drive straight to them",
           .init_only = true,
           .path = PathRole::kInput})),
      plan_margin_(declare_float("plan_margin", 0.05,
                                 {.doc = "m kept beyond the circle round the chassis' outline when planning",
                                  .min = 0.0,
                                  .max = 5.0,
                                  .unit = "m"})),
      replan_blocked_ms_(declare_float(
          "replan_blocked_ms", 2000.0,
          {.doc = "plan again round what the scanner sees after standing BLOCKED this long on a planned way (0: never)",
           .min = 0,
           .max = 600000,
           .unit = "ms"})) {
  set_command_slot_size(sizeof(tims::MessageHeader) + sizeof(PlanRequest) + 64);
}

void Pilot::init() {
  // mode (its Spec's choices) and destination (check_parameters) are checked before.
  rpc_buffer_.assign(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(PathData) + 256, std::byte{0});
  const std::string map = map_.get_string();
  if (!map.empty()) {
    auto loaded = maps::load_map(map);
    if (!loaded.ok()) throw std::runtime_error("map: " + loaded.error_text());
    try {
      planner_.set_map(*loaded.map);
    } catch (const std::exception& e) {
      throw std::runtime_error("map " + map + ": " + e.what());
    }
  }
}

bool Pilot::check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept {
  char dest[wire::kParamStringLen];
  values.copy_string(destination_, dest, sizeof dest);
  double x = 0.0, y = 0.0;
  if (dest[0] != '\0' && !parse_destination(dest, x, y)) {
    problem.set(destination_, "not \"x,y\" (two finite numbers in metres, map frame) or \"\"");
    return false;
  }
  return true;
}

bool Pilot::parse_destination(const char* text, double& x, double& y) const noexcept {
  char* end = nullptr;
  x = std::strtod(text, &end);
  if (end == text) return false;
  const char* p = end;
  while (*p == ' ') ++p;
  if (*p != ',') return false;
  ++p;
  y = std::strtod(p, &end);
  if (end == p) return false;
  p = end;
  while (*p == ' ') ++p;
  return *p == '\0' && std::isfinite(x) && std::isfinite(y);
}

HookResult Pilot::on() {
  const tims::Address chassis = resolved(chassis_);
  const tims::Address path = path_.source();
  data_ = PilotData{};
  have_path_ = path_fresh_ = have_scan_ = false;
  have_plan_ = plan_fresh_ = plan_asked_ = join_path_ = false;
  blocked_since_ns_ = 0;
  destination_writes_ = destination_.write_count();
  position_mono_ns_ = scan_mono_ns_ = 0;
  orders_.clear();  // orders given while OFF do not count
  // Cascading ON of the chassis it drives (its inputs are on and subscribed already).
  if (switch_on(chassis) != HookResult::kOk) return HookResult::kError;
  // The outline, margin and limits the chassis reports.
  auto& ep = command_endpoint();
  const auto r = ep.call(chassis, interfaces::kChassisGetParams, std::span<std::byte>(rpc_buffer_),
                         settings().rpc_timeout_ns);
  if (r.status != tims::CallStatus::kOk || r.reply.type != interfaces::kChassisParamsReply ||
      !wire::read_payload(r.body, tims::body_is_native(r.reply), limits_)) {
    set_error_reason("the chassis did not answer GET_PARAMS");
    return HookResult::kError;
  }
  outline_ = Outline{limits_.boundary_front, limits_.boundary_back, limits_.boundary_left, limits_.boundary_right,
                     limits_.safety_margin};
  plan_radius_ = std::hypot(std::max(outline_.front, outline_.back), std::max(outline_.left, outline_.right));
  interfaces::ChassisSetActivePilot claim;
  claim.pilot = address().raw();
  if (!ep.call(chassis, interfaces::kChassisSetActivePilot, claim, std::span<std::byte>(rpc_buffer_),
               settings().rpc_timeout_ns)
           .ok()) {
    set_error_reason("the chassis refused SET_ACTIVE_PILOT");
    return HookResult::kError;
  }
  if (path.raw() != 0) {
    // A path made before we subscribed is not sent again: fetch the newest.
    const auto pr = ep.call(path, tims::msg::kGetData, std::span<std::byte>(rpc_buffer_), settings().rpc_timeout_ns);
    wire::SampleHeader sh;
    if (pr.status == tims::CallStatus::kOk && pr.reply.type == tims::msg::kData &&
        read_sample(pr.reply, pr.body, sh, path_.value()) && path_.value().point_count >= 2) {
      have_path_ = path_fresh_ = true;
    }
  }
  char mode[16];
  mode_.copy_string(mode, sizeof mode);
  data_.mode = u8(std::strcmp(mode, "path") == 0 && path.raw() != 0 ? PilotMode::kFollowPath : PilotMode::kHold);
  destination_.copy_string(last_destination_, sizeof last_destination_);
  double x = 0.0, y = 0.0;
  if (last_destination_[0] != '\0' && parse_destination(last_destination_, x, y)) {
    line_pending_ = true;
    data_.mode = u8(PilotMode::kDestination);
    data_.target_x = x;
    data_.target_y = y;
  }
  return HookResult::kOk;
}

void Pilot::off() {
  auto& ep = command_endpoint();
  const tims::Address chassis = resolved(chassis_);
  (void)ep.call(chassis, interfaces::kChassisMove, ChassisMove{}, std::span<std::byte>(rpc_buffer_),
                settings().rpc_timeout_ns);
  // Release the chassis if it is still ours (never take it from another pilot).
  const auto r = ep.call(chassis, tims::msg::kGetData, std::span<std::byte>(rpc_buffer_), settings().rpc_timeout_ns);
  wire::SampleHeader sh;
  interfaces::ChassisData c;
  if (r.status == tims::CallStatus::kOk && r.reply.type == tims::msg::kData && read_sample(r.reply, r.body, sh, c) &&
      c.active_pilot == address().raw()) {
    (void)ep.call(chassis, interfaces::kChassisSetActivePilot, interfaces::ChassisSetActivePilot{},
                  std::span<std::byte>(rpc_buffer_), settings().rpc_timeout_ns);
  }
}

Pilot::Clearance Pilot::clearance(const Scan2dData& scan, const Outline& o) noexcept {
  Clearance c;
  c.free_ahead = scan.max_range > 0.0F ? static_cast<double>(scan.max_range) : 1e3;
  const double turn_radius = std::hypot(std::max(o.front, o.back), std::max(o.left, o.right)) + 0.02;
  const uint32_t n = std::min(scan.point_count, interfaces::kScan2dMaxPoints);
  for (uint32_t i = 0; i < n; ++i) {
    if (scan.type[i] == interfaces::kScanPointMaxRange) continue;
    const double x = scan.x[i];
    const double y = scan.y[i];
    const bool in_corridor = y <= o.left + o.margin && y >= -(o.right + o.margin);
    if (in_corridor && x >= -(o.back + o.margin) && x <= o.front + o.margin) c.inside = true;
    if (in_corridor && x > o.front) c.free_ahead = std::min(c.free_ahead, x - o.front);
    if (std::hypot(x, y) < turn_radius) c.turn_blocked = true;
  }
  return c;
}

bool Pilot::handle_input(int64_t now) noexcept {
  const Received r = receive([&](const InputPort& from) {
    if (&from == &position_) {
      position_mono_ns_ = now;
    } else if (&from == &scan2d_) {
      scan_mono_ns_ = now;
      have_scan_ = true;
    } else {
      have_path_ = path_.value().point_count >= 2;
      path_fresh_ = true;
    }
  });
  return r.failed;  // position or scan2d left ENABLED: their data stopped (the reason is set)
}

bool Pilot::path_goal(const PathData& p, bool& fresh, const Pose2d& pose, double& gx, double& gy,
                      double& remaining) noexcept {
  const uint32_t n = std::min(p.point_count, interfaces::kPathMaxPoints);
  const bool closed = p.closed != 0;
  const auto dist2 = [&](uint32_t i) {
    const double dx = static_cast<double>(p.x[i]) - pose.x;
    const double dy = static_cast<double>(p.y[i]) - pose.y;
    return dx * dx + dy * dy;
  };
  uint32_t index = data_.path_index < n ? data_.path_index : 0;
  if (fresh) {  // a new path: start from the nearest point
    index = 0;
    for (uint32_t i = 1; i < n; ++i) {
      if (dist2(i) < dist2(index)) index = i;
    }
    fresh = false;
  } else {  // progress: the nearest point a little way ahead (never backwards)
    uint32_t best = index;
    for (uint32_t k = 1; k < 64 && (closed || index + k < n); ++k) {
      const uint32_t i = (index + k) % n;
      if (dist2(i) < dist2(best)) best = i;
    }
    if (closed && best < index) ++data_.laps;  // went round past the first point
    index = best;
  }
  data_.path_index = index;
  // The look-ahead point: the first point at least `lookahead` away, walking forward.
  const double look2 = lookahead_.get_float() * lookahead_.get_float();
  uint32_t goal = index;
  for (uint32_t k = 0; k < n; ++k) {
    const uint32_t i = closed ? (index + k) % n : index + k;
    if (i >= n) break;
    goal = i;
    if (dist2(i) >= look2) break;
  }
  gx = p.x[goal];
  gy = p.y[goal];
  data_.target_x = p.x[closed ? goal : n - 1];
  data_.target_y = p.y[closed ? goal : n - 1];
  if (closed) {
    remaining = -1.0;
    return true;
  }
  // Open path: the distance still to drive, for braking; finished at the last point.
  remaining = std::sqrt(dist2(index));
  for (uint32_t i = index; i + 1 < n; ++i) {
    remaining += std::hypot(static_cast<double>(p.x[i + 1] - p.x[i]), static_cast<double>(p.y[i + 1] - p.y[i]));
  }
  return !(index + 2 >= n && std::sqrt(dist2(n - 1)) < goal_tolerance_.get_float());
}

void Pilot::steer(const Pose2d& pose, double gx, double gy, double final_distance) noexcept {
  const Pose2d rel = between(pose, Pose2d{gx, gy, 0.0});
  const double l2 = rel.x * rel.x + rel.y * rel.y;
  const double alpha = std::atan2(rel.y, rel.x);
  goal_bearing_ = alpha;
  const double vmax = std::min(vx_max_.get_float(), limits_.vx_max);
  const double wmax = std::min(omega_max_.get_float(), limits_.omega_max);
  const double brake = brake_fraction_.get_float() * limits_.dec_max;
  double v = 0.0;
  double w = 0.0;
  if (std::abs(alpha) > turn_in_place_deg_.get_float() * std::numbers::pi / 180.0 || l2 < 1e-6) {
    w = std::clamp(2.0 * alpha, -wmax, wmax);  // turn on the spot towards the goal
  } else {
    const double kappa = 2.0 * rel.y / l2;  // the arc through the goal (pure pursuit)
    v = vmax;
    if (std::abs(kappa) > 1e-9) v = std::min(v, wmax / std::abs(kappa));
    if (final_distance >= 0.0) v = std::min(v, std::max(limits_.vx_min, std::sqrt(2.0 * brake * final_distance)));
    v = std::min(v, data_.speed_limit);
    w = std::clamp(v * kappa, -wmax, wmax);
  }
  data_.vx = v;
  data_.omega = w;
}

void Pilot::send_move(double vx, double omega) noexcept {
  alignas(8) std::byte buf[256];
  ChassisMove m;
  m.vx = vx;
  m.omega = omega;
  const auto r = data_endpoint().call(resolved(chassis_), interfaces::kChassisMove, m, std::span<std::byte>(buf),
                                      settings().rpc_timeout_ns);
  if (r.status == tims::CallStatus::kOk && r.reply.type == tims::msg::kError) {
    ++data_.moves_refused;  // another pilot has the chassis: stand until told again
    data_.mode = u8(PilotMode::kHold);
    data_.status = u8(PilotStatus::kPreempted);
    data_.vx = data_.omega = 0.0;
  }
}

HookResult Pilot::loop() {
  const int64_t now = rt::monotonic_ns();
  if (handle_input(now)) return HookResult::kError;  // a source went away: re-subscribed on retry

  // New orders: commands first, then a changed `destination` parameter.
  bool reclaim = false;
  if (orders_.take(order_)) {
    const Order& o = order_;
    switch (o.kind) {
      case Request::kNone: break;
      case Request::kFollowPath:
        data_.mode = u8(PilotMode::kFollowPath);
        path_fresh_ = true;
        break;
      case Request::kHold:
        data_.mode = u8(PilotMode::kHold);
        data_.status = u8(PilotStatus::kIdle);
        break;
      case Request::kDestination:
        data_.mode = u8(PilotMode::kDestination);
        data_.target_x = o.x;
        data_.target_y = o.y;
        line_pending_ = true;
        have_plan_ = false;  // planned on a later cycle (when there is a map)
        plan_asked_ = false;
        break;
      case Request::kPlanned:
        data_.mode = u8(PilotMode::kDestination);
        data_.target_x = o.x;
        data_.target_y = o.y;
        std::memcpy(&plan_data_, &o.plan, sizeof plan_data_);
        have_plan_ = plan_fresh_ = true;
        plan_asked_ = false;
        blocked_since_ns_ = 0;
        break;
      case Request::kPlanFailed:
        plan_asked_ = false;
        blocked_since_ns_ = 0;
        // No way even on the map alone: stand. (Round obstacles only: try again later.)
        if (o.x == data_.target_x && o.y == data_.target_y && !have_plan_) {
          if (join_path_) {  // no way back to the path now: follow it (blocked) and try again later
            join_path_ = false;
            data_.mode = u8(PilotMode::kFollowPath);
            path_fresh_ = true;
          } else {
            data_.mode = u8(PilotMode::kHold);
            data_.status = u8(PilotStatus::kUnreachable);
          }
        }
        break;
    }
    if (o.kind != Request::kNone && o.kind != Request::kPlanned && o.kind != Request::kPlanFailed) join_path_ = false;
    reclaim = o.kind != Request::kNone && o.kind != Request::kPlanFailed;
  }
  // The `destination` parameter: every SET_PARAM is an order (also "" after a
  // SET_DESTINATION, when the text itself did not change).
  char text[wire::kParamStringLen];
  const uint32_t writes = destination_.write_count();
  destination_.copy_string(text, sizeof text);
  if (writes != destination_writes_ || std::strcmp(text, last_destination_) != 0) {
    destination_writes_ = writes;
    join_path_ = false;
    std::memcpy(last_destination_, text, sizeof text);
    double x = 0.0, y = 0.0;
    if (text[0] == '\0') {
      data_.mode = u8(path_.configured() ? PilotMode::kFollowPath : PilotMode::kHold);
      path_fresh_ = true;
      reclaim = true;
      log_info("destination \"\": %s", path_.configured() ? "following the path" : "holding");
    } else if (parse_destination(text, x, y)) {
      data_.mode = u8(PilotMode::kDestination);
      data_.target_x = x;
      data_.target_y = y;
      line_pending_ = true;
      have_plan_ = plan_asked_ = false;
      reclaim = true;
      log_info("destination (%.2f, %.2f) set by parameter", x, y);
    } else {
      ++data_.bad_destinations;
    }
  }
  if (reclaim && data_.status == u8(PilotStatus::kPreempted)) {
    alignas(8) std::byte buf[256];
    interfaces::ChassisSetActivePilot claim;
    claim.pilot = address().raw();
    (void)data_endpoint().call(resolved(chassis_), interfaces::kChassisSetActivePilot, claim, std::span<std::byte>(buf),
                               settings().rpc_timeout_ns);
    data_.status = u8(PilotStatus::kIdle);
  }
  if (data_.status == u8(PilotStatus::kPreempted)) {  // stand without MOVEs (they would be refused)
    publish(data_, rt::host_time_ns());
    return HookResult::kOk;
  }

  const int64_t timeout = silence_ns();
  const bool fresh = position_mono_ns_ > 0 && now - position_mono_ns_ <= timeout && have_scan_ &&
                     now - scan_mono_ns_ <= timeout;
  const Pose2d pose{position_.value().x, position_.value().y, position_.value().phi};
  data_.pose_x = pose.x;
  data_.pose_y = pose.y;
  data_.pose_phi = pose.phi;
  const double previous_vx = data_.vx;
  data_.vx = data_.omega = 0.0;

  // The obstacle speed limit from the newest scan.
  const Clearance c = have_scan_ ? clearance(scan2d_.value(), outline_) : Clearance{};
  data_.obstacle_distance = c.free_ahead;
  const double brake = brake_fraction_.get_float() * limits_.dec_max;
  // Keep the margin, and allow for one cycle of travel before the next scan is seen.
  const double usable = c.free_ahead - outline_.margin - previous_vx * static_cast<double>(period_ns()) * 1e-9;
  data_.speed_limit = c.inside ? 0.0 : std::sqrt(2.0 * brake * std::max(0.0, usable));

  const auto mode = static_cast<PilotMode>(data_.mode);
  const bool planning = planner_.has_map() && mode == PilotMode::kDestination && !have_plan_;
  if (mode == PilotMode::kHold) {
    if (data_.status != u8(PilotStatus::kUnreachable)) data_.status = u8(PilotStatus::kIdle);
  } else if (!fresh) {
    data_.status = u8(PilotStatus::kNoInput);
  } else if (mode == PilotMode::kFollowPath && !have_path_) {
    data_.status = u8(PilotStatus::kNoPath);
  } else if (planning) {
    // Ask the command task for the way (again after a second, should a request be lost).
    if (!plan_asked_ || now - plan_asked_ns_ > rt::kNsPerSec) ask_for_plan(pose, false);
    data_.status = u8(PilotStatus::kPlanning);
  } else {
    double gx = data_.target_x, gy = data_.target_y, remaining = 0.0;
    bool going = true;
    if (mode == PilotMode::kFollowPath) {
      going = path_goal(path_.value(), path_fresh_, pose, gx, gy, remaining);
    } else if (have_plan_) {
      going = path_goal(plan_data_, plan_fresh_, pose, gx, gy, remaining);
      data_.target_x = plan_data_.x[plan_data_.point_count - 1];
      data_.target_y = plan_data_.y[plan_data_.point_count - 1];
      // path_goal ends within goal_tolerance of the way's last point (float): also the destination.
      going = going || std::hypot(data_.target_x - pose.x, data_.target_y - pose.y) >= goal_tolerance_.get_float();
    } else {
      if (line_pending_) {
        line_x_ = pose.x;
        line_y_ = pose.y;
        line_pending_ = false;
      }
      remaining = std::hypot(gx - pose.x, gy - pose.y);
      going = remaining >= goal_tolerance_.get_float();
      // The look-ahead point on the line: `lookahead` beyond the robot's projection.
      const double lx = data_.target_x - line_x_;
      const double ly = data_.target_y - line_y_;
      const double len = std::hypot(lx, ly);
      if (len > 1e-6) {
        const double t = ((pose.x - line_x_) * lx + (pose.y - line_y_) * ly) / len;
        const double at = std::clamp(t + lookahead_.get_float(), 0.0, len);
        gx = line_x_ + lx / len * at;
        gy = line_y_ + ly / len * at;
      }
    }
    if (!going && join_path_) {  // the planned way back to the path ends: follow it again
      join_path_ = false;
      data_.mode = u8(PilotMode::kFollowPath);
      path_fresh_ = true;
      data_.status = u8(PilotStatus::kDriving);
      log_info("back on the path at (%.2f, %.2f)", pose.x, pose.y);
    } else if (!going) {
      data_.status = u8(PilotStatus::kReached);
    } else {
      steer(pose, gx, gy, remaining);
      data_.status = u8(PilotStatus::kDriving);
      if (c.inside || (data_.vx == 0.0 && data_.speed_limit <= 0.0)) {
        // Blocked: stand. Turning on the spot towards the goal is safe when nothing is
        // within the turning circle (and lets the robot face a path that bends away).
        data_.vx = 0.0;
        const double wmax = std::min(omega_max_.get_float(), limits_.omega_max);
        data_.omega = c.turn_blocked ? 0.0 : std::clamp(2.0 * goal_bearing_, -wmax, wmax);
        if (blocked_since_ns_ == 0) {
          blocked_since_ns_ = now;
          log_info("BLOCKED at (%.2f, %.2f): something %.2f m ahead of the outline%s", pose.x, pose.y, c.free_ahead,
                   have_plan_ && mode == PilotMode::kDestination ? "" : " (standing until it is gone)");
        }
        data_.status = u8(PilotStatus::kBlocked);
        ++data_.blocked_cycles;
        const int64_t replan_ns = std::llround(replan_blocked_ms_.get_float() * 1e6);
        if (have_plan_ && mode == PilotMode::kDestination && replan_ns > 0 && now - blocked_since_ns_ >= replan_ns &&
            !plan_asked_) {
          log_info("BLOCKED for %lld ms: planning again round what the scanner sees",
                   static_cast<long long>((now - blocked_since_ns_) / rt::kNsPerMs));
          ask_for_plan(pose, true);
        } else if (mode == PilotMode::kFollowPath && planner_.has_map() && replan_ns > 0 &&
                   now - blocked_since_ns_ >= replan_ns && !plan_asked_) {
          // Off the path behind something (a wall after a bad estimate, a room): plan a
          // way to the path's look-ahead point, then follow the path again.
          log_info("BLOCKED for %lld ms off the path: planning a way back to it at (%.2f, %.2f)",
                   static_cast<long long>((now - blocked_since_ns_) / rt::kNsPerMs), gx, gy);
          join_path_ = true;
          data_.mode = u8(PilotMode::kDestination);
          data_.target_x = gx;
          data_.target_y = gy;
          have_plan_ = false;
          ask_for_plan(pose, true);
        }
      }
    }
  }
  if (data_.status != u8(PilotStatus::kBlocked)) blocked_since_ns_ = 0;
  data_.distance_to_target = std::hypot(data_.target_x - pose.x, data_.target_y - pose.y);
  send_move(data_.vx, data_.omega);
  publish(data_, rt::host_time_ns());
  return HookResult::kOk;
}

void Pilot::ask_for_plan(const Pose2d& pose, bool replan) noexcept {
  PlanRequest r;
  r.gx = data_.target_x;
  r.gy = data_.target_y;
  r.x = pose.x;
  r.y = pose.y;
  r.phi = pose.phi;
  r.replan = replan ? 1 : 0;
  if (replan && have_scan_) {
    // The scan points near the robot, in the map frame (the map lacks them).
    const uint32_t n = std::min(scan2d_.value().point_count, interfaces::kScan2dMaxPoints);
    const double c = std::cos(pose.phi), s = std::sin(pose.phi);
    for (uint32_t i = 0; i < n && r.obstacles < kPlanObstacles; i += 2) {
      if (scan2d_.value().type[i] == interfaces::kScanPointMaxRange) continue;
      const double x = scan2d_.value().x[i], y = scan2d_.value().y[i];
      if (std::hypot(x, y) > 2.0) continue;
      r.ox[r.obstacles] = static_cast<float>(pose.x + c * x - s * y);
      r.oy[r.obstacles] = static_cast<float>(pose.y + s * x + c * y);
      ++r.obstacles;
    }
  }
  const tims::ConstBuffer part = tims::buffer_of(r);
  (void)data_endpoint().send(address(), kPlanSelf, std::span<const tims::ConstBuffer>(&part, 1));
  plan_asked_ = true;
  plan_asked_ns_ = rt::monotonic_ns();
}

void Pilot::give_order(Request kind, double x, double y, const interfaces::PathData* plan) noexcept {
  orders_.post([&](Order& o) {  // the newest order wins
    o.kind = kind;
    o.x = x;
    o.y = y;
    if (plan != nullptr) std::memcpy(&o.plan, plan, sizeof o.plan);
  });
}

const char* Pilot::plan_way(const PlanRequest& r) noexcept {
  planner_.clear_obstacles();
  const double radius = plan_radius_ + plan_margin_.get_float();
  for (uint32_t i = 0; i < std::min(r.obstacles, kPlanObstacles); ++i) planner_.add_obstacle(r.ox[i], r.oy[i], radius);
  interfaces::PathMake w;
  const GridPlanner::Result result = planner_.plan(r.x, r.y, r.gx, r.gy,
                                                   GridPlanner::Options{.radius = radius, .comfort = 0.3}, w);
  if (result.error != nullptr) return result.error;
  if (const char* why = Path::make_path(w, 0.1, plan_scratch_)) return why;
  log_info("way to (%.2f, %.2f) planned: %.1f m, %u waypoints, %u cells searched%s", r.gx, r.gy, result.length, w.count,
           result.expanded, result.start_moved ? " (the robot stands too near a wall: it backs out first)" : "");
  give_order(Request::kPlanned, r.gx, r.gy, &plan_scratch_);
  return nullptr;
}

CommandResult Pilot::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  switch (request.type) {
    case kPlanSelf: {
      // Only from this pilot's own data task; to anyone else an unknown command.
      if (!(request.source() == data_endpoint().address())) return CommandResult::kUnknown;
      PlanRequest r;
      if (body.size() != sizeof r) return CommandResult::kHandled;
      std::memcpy(&r, body.data(), sizeof r);
      if (const char* why = plan_way(r)) {
        if (r.replan != 0) {
          log_info("no way round what blocks the robot (%s): standing, trying again later", why);
        } else {
          log_warning("destination (%.2f, %.2f) unreachable: %s", r.gx, r.gy, why);
        }
        give_order(Request::kPlanFailed, r.gx, r.gy);
      }
      return CommandResult::kHandled;  // no reply: the data task does not wait
    }
    case interfaces::kPilotSetDestination: {
      interfaces::PilotDestination d;
      if (!wire::read_payload(body, tims::body_is_native(request), d) || !std::isfinite(d.x) || !std::isfinite(d.y)) {
        reject_malformed(request, "SET_DESTINATION: body must be two finite doubles x, y");
        return CommandResult::kHandled;
      }
      log_info("SET_DESTINATION (%.2f, %.2f) from %s", d.x, d.y, request.source());
      if (planner_.has_map() && state() == ComponentState::kEnabled) {
        // Plan now from the newest estimate, so that a destination with no way is refused.
        const auto pr = command_endpoint().call(resolved(position_.source_parameter()), tims::msg::kGetData,
                                                std::span<std::byte>(rpc_buffer_), settings().rpc_timeout_ns);
        wire::SampleHeader sh;
        PositionData pos;
        if (pr.status == tims::CallStatus::kOk && pr.reply.type == tims::msg::kData &&
            read_sample(pr.reply, pr.body, sh, pos)) {
          PlanRequest r;
          r.gx = d.x;
          r.gy = d.y;
          r.x = pos.x;
          r.y = pos.y;
          r.phi = pos.phi;
          if (const char* why = plan_way(r)) {
            log_warning("SET_DESTINATION (%.2f, %.2f) refused: %s", d.x, d.y, why);
            wire::ErrorText text;
            wire::copy_text(text.text, "SET_DESTINATION: ");
            wire::append_text(text.text, why);
            reply_with(request, tims::msg::kError, text);
            return CommandResult::kHandled;
          }
          break;  // planned: handed to the data task
        }
      }
      give_order(Request::kDestination, d.x, d.y);
      break;
    }
    case interfaces::kPilotFollowPath:
    case interfaces::kPilotHold: {
      if (!body.empty()) {
        reject_malformed(request, "FOLLOW_PATH and HOLD take no body");
        return CommandResult::kHandled;
      }
      if (request.type == interfaces::kPilotFollowPath && resolved(path_.source_parameter()).raw() == 0) {
        reply_error(request, "FOLLOW_PATH: no 'path' component configured");
        return CommandResult::kHandled;
      }
      log_info("%s from %s", request.type == interfaces::kPilotHold ? "HOLD" : "FOLLOW_PATH", request.source());
      give_order(request.type == interfaces::kPilotHold ? Request::kHold : Request::kFollowPath);
      break;
    }
    default: return CommandResult::kUnknown;
  }
  reply(request, tims::msg::kOk);
  return CommandResult::kHandled;
}

}  // namespace rack::components
