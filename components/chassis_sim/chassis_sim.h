// ChassisSim (class Chassis): a simulated drive. Each period it ramps the measured
// velocities towards the commanded ones (acceleration limits), integrates the true
// pose, and publishes the odometry increments with seeded noise, plus the true pose
// (truth_*) for evaluating localisation.
//
// With a `map` (map_server YAML), the robot's outline never enters an occupied cell:
// a step that would is not taken, the robot stands (velocities zero) and the step is
// counted in `collisions`. A missing or malformed map puts the component in ERROR
// with the loader's message.
//
// Who may drive: only the active pilot (SET_ACTIVE_PILOT) may MOVE; anyone else gets
// ERROR. Changing the active pilot stops the robot. A command watchdog stops the
// robot when no MOVE arrived for `watchdog_ms` (counted in watchdog_stops).
//
// Threads: the command task (MOVE, SET_ACTIVE_PILOT, GET_PARAMS) and the periodic
// data task share the commanded velocity under a PI mutex.
// Real-time contract: on(), off(), loop() and command() are RT-safe; init() allocates
// (the RNG).
#pragma once

#include <atomic>
#include <optional>
#include <random>

#include "common/chassis_base.h"
#include "common/pose2d.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/robot.h"
#include "rack/maps/occupancy_map.h"

namespace rack::components {

class ChassisSim final : public ChassisBase {
 public:
  ChassisSim();

  // The velocity a ramp reaches after dt: towards `target`, at most `acc` faster or
  // `dec` slower in magnitude (braking includes reversing through zero). RT-safe.
  [[nodiscard]] static double ramp(double current, double target, double acc, double dec, double dt) noexcept;

 protected:
  void init() override;
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT
  // MOVE, SET_ACTIVE_PILOT, GET_PARAMS: ChassisBase.
  [[nodiscard]] interfaces::ChassisParams chassis_params() const noexcept override;
  [[nodiscard]] double vy_max() const noexcept override;

 private:
  [[nodiscard]] double gauss(double sigma) noexcept;
  // True when the outline at `pose` covers an occupied map cell. RT-safe.
  [[nodiscard]] bool collides(const Pose2d& pose) const noexcept;

  Parameter& vx_max_;
  Parameter& vx_min_;
  Parameter& vy_max_;
  Parameter& omega_max_;
  Parameter& acc_max_;
  Parameter& dec_max_;
  Parameter& omega_acc_max_;
  Parameter& boundary_front_;
  Parameter& boundary_back_;
  Parameter& boundary_left_;
  Parameter& boundary_right_;
  Parameter& safety_margin_;
  Parameter& watchdog_ms_;
  Parameter& noise_xy_;
  Parameter& noise_phi_;
  Parameter& noise_phi_per_m_;
  Parameter& odometry_scale_;
  Parameter& seed_;
  Parameter& initial_x_;
  Parameter& initial_y_;
  Parameter& initial_phi_;
  Parameter& battery_;
  Parameter& map_;

  std::optional<maps::OccupancyMap> map_data_;  // loaded in init(), immutable after

  // Data task state (on() sets it while the data task is idle).
  Velocity command_;  // the newest MOVE (take_velocity), or a stop by the watchdog
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  Velocity measured_;
  Pose2d truth_;
  int64_t last_loop_ns_ = 0;
  uint32_t watchdog_stops_ = 0;
  uint32_t collisions_ = 0;
  bool touching_ = false;  // against a wall since the last collision (GDOS: once per contact)
};

}  // namespace rack::components
