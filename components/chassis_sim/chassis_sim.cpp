#include "chassis_sim/chassis_sim.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

namespace rack::components {

using interfaces::ChassisData;
using interfaces::ChassisParams;

ChassisSim::ChassisSim()
    : ChassisBase(DataTaskMode::kPeriodic),
      vx_max_(declare_float("vx_max", 1.0, {.doc = "m/s, fastest forward/backward speed", .min = 0.0, .max = 20.0})),
      vx_min_(
          declare_float("vx_min", 0.05, {.doc = "m/s, slowest useful speed (told to pilots)", .min = 0.0, .max = 5.0})),
      vy_max_(declare_float("vy_max", 0.0,
                            {.doc = "m/s, sideways limit (0: differential drive)", .min = 0.0, .max = 20.0})),
      omega_max_(declare_float("omega_max", 1.5, {.doc = "rad/s, fastest turn", .min = 0.0, .max = 20.0})),
      acc_max_(declare_float("acc_max", 1.0, {.doc = "m/s^2, speeding up", .min = 0.01, .max = 50.0})),
      dec_max_(declare_float("dec_max", 2.0, {.doc = "m/s^2, braking", .min = 0.01, .max = 50.0})),
      omega_acc_max_(declare_float("omega_acc_max", 4.0,
                                   {.doc = "rad/s^2, turn acceleration and braking", .min = 0.01, .max = 100.0})),
      boundary_front_(declare_float("boundary_front", 0.30,
                                    {.doc = "m, outline ahead of the reference point", .min = 0.0, .max = 10.0})),
      boundary_back_(declare_float("boundary_back", 0.30,
                                   {.doc = "m, outline behind the reference point", .min = 0.0, .max = 10.0})),
      boundary_left_(declare_float("boundary_left", 0.25, {.doc = "m, outline to the left", .min = 0.0, .max = 10.0})),
      boundary_right_(
          declare_float("boundary_right", 0.25, {.doc = "m, outline to the right", .min = 0.0, .max = 10.0})),
      safety_margin_(declare_float(
          "safety_margin", 0.10, {.doc = "m, kept free around the outline (told to pilots)", .min = 0.0, .max = 5.0})),
      watchdog_ms_(
          declare_float("watchdog_ms", 500.0,
                        {.doc = "stop when no MOVE came for this long", .min = 10, .max = 60000, .unit = "ms"})),
      noise_xy_(declare_float(
          "noise_xy", 0.02,
          {.doc = "odometry translation noise, m per sqrt(m) travelled (std-dev)", .min = 0.0, .max = 1.0})),
      noise_phi_(declare_float(
          "noise_phi", 0.02,
          {.doc = "odometry rotation noise, rad per sqrt(rad) turned (std-dev)", .min = 0.0, .max = 1.0})),
      noise_phi_per_m_(declare_float(
          "noise_phi_per_m", 0.01,
          {.doc = "odometry rotation noise from driving, rad per sqrt(m) (std-dev)", .min = 0.0, .max = 1.0})),
      odometry_scale_(
          declare_float("odometry_scale", 1.0,
                        {.doc = "systematic scale of the reported translation (1: none)", .min = 0.5, .max = 1.5})),
      seed_(declare_int(
          "seed", 1,
          {.doc = "seed of the noise generator (same seed, same noise)", .min = 0, .max = 1e15, .init_only = true})),
      initial_x_(declare_float("initial_x", 0.0, {.doc = "m, true start pose in the map frame", .init_only = true})),
      initial_y_(declare_float("initial_y", 0.0, {.doc = "m, true start pose in the map frame", .init_only = true})),
      initial_phi_(declare_float("initial_phi", 0.0,
                                 {.doc = "rad, true start heading", .min = -7.0, .max = 7.0, .init_only = true})),
      battery_(declare_float("battery_v", 24.0,
                             {.doc = "V, the battery voltage reported", .min = 0.0, .max = 1000.0, .unit = "V"})),
      map_(declare_string(
          "map", "",
          {.doc =
               "optional map_server YAML: the robot stops at occupied cells (\"\": no walls; relative: to the host file's folder)",
           .init_only = true,
           .path = PathRole::kInput})) {}

void ChassisSim::init() {
  const std::string path = map_.get_string();
  if (!path.empty()) {
    auto loaded = maps::load_map(path);
    if (!loaded.ok()) throw std::runtime_error("map: " + loaded.error_text());
    map_data_ = std::move(loaded.map);
  }
  rng_.seed(static_cast<uint64_t>(seed_.get_int()));
  truth_ = Pose2d{initial_x_.get_float(), initial_y_.get_float(), normalize_angle(initial_phi_.get_float())};
}

double ChassisSim::ramp(double current, double target, double acc, double dec, double dt) noexcept {
  // Braking when the target is slower or on the other side of zero.
  const bool braking = std::abs(target) < std::abs(current) || target * current < 0.0;
  const double step = (braking ? dec : acc) * dt;
  return current + std::clamp(target - current, -step, step);
}

double ChassisSim::gauss(double sigma) noexcept { return sigma > 0.0 ? sigma * normal_(rng_) : 0.0; }

HookResult ChassisSim::on() {
  // The pose is the world's: it survives OFF/ON (only init() places the robot).
  command_velocity(Velocity{});
  command_ = measured_ = Velocity{};
  reset_pilot();
  last_loop_ns_ = 0;
  watchdog_stops_ = 0;
  collisions_ = 0;
  touching_ = false;
  return HookResult::kOk;
}

void ChassisSim::off() {
  // A switched-off drive stands: no ramp-down is simulated.
  command_velocity(Velocity{});
  measured_ = Velocity{};
}

HookResult ChassisSim::loop() {
  const int64_t now = rt::monotonic_ns();
  // Simulated time is real time: an overrun integrates the longer interval (bounded,
  // so that a stalled task does not teleport the robot).
  double dt = static_cast<double>(period_ns()) * 1e-9;
  if (last_loop_ns_ != 0) dt = std::clamp(static_cast<double>(now - last_loop_ns_) * 1e-9, 0.0, 10.0 * dt);
  last_loop_ns_ = now;

  (void)take_velocity(command_);
  const bool moving = command_.vx != 0.0 || command_.vy != 0.0 || command_.omega != 0.0;
  if (moving && now - last_move_ns() > std::llround(watchdog_ms_.get_float() * 1e6)) {
    command_ = Velocity{};
    ++watchdog_stops_;
  }
  const Velocity target = command_;
  const double acc = acc_max_.get_float();
  const double dec = dec_max_.get_float();
  const double wacc = omega_acc_max_.get_float();
  measured_.vx = ramp(measured_.vx, target.vx, acc, dec, dt);
  measured_.vy = ramp(measured_.vy, target.vy, acc, dec, dt);
  measured_.omega = ramp(measured_.omega, target.omega, wacc, wacc, dt);

  Pose2d motion = integrate_twist(measured_.vx, measured_.vy, measured_.omega, dt);
  const Pose2d next = compose(truth_, motion);
  if (map_data_ && (motion.x != 0.0 || motion.y != 0.0 || motion.phi != 0.0) && collides(next)) {
    // A wall: the robot stands where it is (a bumper stop), nothing is reported moved.
    motion = Pose2d{};
    if (!touching_) {  // once per contact (it stays until a move gets free)
      touching_ = true;
      log_info("collision with a wall at (%.2f, %.2f), heading %.0f deg: stopped", truth_.x, truth_.y,
               truth_.phi * 180.0 / 3.141592653589793);
    }
    measured_ = Velocity{};
    ++collisions_;
  } else {
    truth_ = next;
    if (motion.x != 0.0 || motion.y != 0.0 || motion.phi != 0.0) touching_ = false;
  }

  // Odometry: the true increment with a random walk whose variance grows with the
  // distance travelled and the angle turned (independent of the period), plus an
  // optional systematic scale error (a wrong wheel radius).
  const double dist = std::hypot(motion.x, motion.y);
  const double turn = std::abs(motion.phi);
  const double scale = odometry_scale_.get_float();
  ChassisData d;
  if (dist > 0.0) {
    const double along = gauss(noise_xy_.get_float() * std::sqrt(dist));
    d.delta_x = motion.x * scale + along * motion.x / dist;
    d.delta_y = motion.y * scale + along * motion.y / dist;
  }
  d.delta_phi = motion.phi + gauss(noise_phi_.get_float() * std::sqrt(turn)) +
                gauss(noise_phi_per_m_.get_float() * std::sqrt(dist));
  d.vx = measured_.vx;
  d.vy = measured_.vy;
  d.omega = measured_.omega;
  d.battery = battery_.get_float();
  d.active_pilot = active_pilot();
  d.watchdog_stops = watchdog_stops_;
  d.truth_valid = 1;
  d.truth_x = truth_.x;
  d.truth_y = truth_.y;
  d.truth_phi = truth_.phi;
  d.collisions = collisions_;
  publish(d, rt::host_time_ns());
  return HookResult::kOk;
}

bool ChassisSim::collides(const Pose2d& pose) const noexcept {
  // The outline's edges, sampled at half the map resolution (a wall is at least one
  // cell thick, so it cannot slip between two samples).
  const double f = boundary_front_.get_float();
  const double b = -boundary_back_.get_float();
  const double l = boundary_left_.get_float();
  const double r = -boundary_right_.get_float();
  const double step = map_data_->resolution() / 2.0;
  const double c = std::cos(pose.phi);
  const double s = std::sin(pose.phi);
  const auto occupied = [&](double x, double y) {
    int ix = 0, iy = 0;
    if (!map_data_->world_to_cell(pose.x + c * x - s * y, pose.y + s * x + c * y, ix, iy)) return false;
    return map_data_->cell_state(ix, iy) == maps::CellState::kOccupied;
  };
  const auto edge = [&](double x0, double y0, double x1, double y1) {
    const double len = std::hypot(x1 - x0, y1 - y0);
    const int n = static_cast<int>(std::ceil(len / step));
    for (int i = 0; i <= n; ++i) {
      const double t = n == 0 ? 0.0 : static_cast<double>(i) / n;
      if (occupied(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t)) return true;
    }
    return false;
  };
  return edge(b, r, f, r) || edge(f, r, f, l) || edge(f, l, b, l) || edge(b, l, b, r);
}

double ChassisSim::vy_max() const noexcept { return vy_max_.get_float(); }

ChassisParams ChassisSim::chassis_params() const noexcept {
  ChassisParams p;
  p.vx_max = vx_max_.get_float();
  p.vx_min = vx_min_.get_float();
  p.omega_max = omega_max_.get_float();
  p.acc_max = acc_max_.get_float();
  p.dec_max = dec_max_.get_float();
  p.boundary_front = boundary_front_.get_float();
  p.boundary_back = boundary_back_.get_float();
  p.boundary_left = boundary_left_.get_float();
  p.boundary_right = boundary_right_.get_float();
  p.safety_margin = safety_margin_.get_float();
  p.watchdog_ns = std::llround(watchdog_ms_.get_float() * 1e6);
  return p;
}

}  // namespace rack::components
