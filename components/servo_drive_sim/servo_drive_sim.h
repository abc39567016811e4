// ServoDriveSim (class ServoDrive): a simulated positioning axis with the commands
// and data of ServoDriveCan (HOME, MOVE_POS with POSITION_REACHED, MOVE_VEL), moving
// with a trapezoidal profile (max_velocity, acceleration) inside [position_min,
// position_max]. Starts homed at `initial_position`. For the simulated 3-D scanner
// (configs/sim_scan3d.yaml: LadarSim turns with it, Scan3D sweeps it) and for tests;
// on a robot, ServoDriveCan takes its place with the same host-file name.
//
// Real-time contract: on(), off(), loop() and command() are RT-safe (atomics and
// arithmetic).
#pragma once

#include <atomic>

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

class ServoDriveSim final : public DataComponent<interfaces::ServoDriveData> {
 public:
  ServoDriveSim();

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, periodic
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  Parameter& initial_position_;
  Parameter& max_velocity_;
  Parameter& acceleration_;
  Parameter& position_min_;
  Parameter& position_max_;
  Parameter& home_position_;

  // Command task -> data task: the newest move, and HOME.
  struct Move {
    double target = 0.0;       // MOVE_POS
    double velocity = 0.0;     // > 0: position move at this speed
    double vel_command = 0.0;  // MOVE_VEL (when is_velocity)
    bool is_velocity = false;
    uint32_t requester = 0;  // told POSITION_REACHED (MOVE_POS)
  };
  Handoff<Move> move_;
  Handoff<bool> home_;
  std::atomic<double> position_reading_{0.0};  // loop() -> HOME (relaxed: a reading)
  std::atomic<uint32_t> moves_{0};

  // Data task only.
  double position_ = 0.0, velocity_ = 0.0, target_ = 0.0, speed_ = 0.0;
  bool velocity_mode_ = false, moving_ = false;
  uint32_t notify_ = 0, reached_ = 0;
  int64_t last_ns_ = 0;
  interfaces::ServoDriveData out_{};
};

}  // namespace rack::components
