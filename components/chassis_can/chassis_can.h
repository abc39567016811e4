// ChassisCan (class Chassis): a differential drive with two CANopen CiA 402 drives in
// profile velocity mode, over SocketCAN ("can0") or a CAN-frame socket of the shipped
// drive simulator ("unix:/path").
//
// on(): per drive, NMT pre-operational, SDO configuration (mode 3 = profile velocity,
// profile acceleration/deceleration, heartbeat producer time, TPDOs on every SYNC),
// the CiA 402 power-up sequence (shutdown, switch on, enable operation, verified by
// reading the statusword), then NMT start. Each SDO waits sdo_timeout_ms.
// loop() (periodic): RPDO1 (controlword, target velocity) to both drives, SYNC, then
// collects TPDO1 (velocity, position) and TPDO2 (statusword) of both within half a
// period, and publishes ChassisData: odometry increments and measured velocities.
//
// Safety:
// - Heartbeats: each drive's heartbeat is monitored; a drive silent for
//   heartbeat_timeout_ms puts the chassis in ERROR and the other drive is stopped at
//   once (quick stop). A drive that leaves OPERATIONAL or reports a fault does the same.
// - Command watchdog (which RACK lacked): no MOVE for watchdog_ms sets the targets to
//   zero and counts a watchdog stop.
// - Active pilot: only the component set by SET_ACTIVE_PILOT may MOVE; changing the
//   pilot stops the robot. MOVE velocities are clamped to vx_max/omega_max.
// - off() (and so every way out of ENABLED) stops both drives and shuts their power
//   stages down.
//
// Real-time contract: loop() and command() use only send/recv/ppoll on the open CAN
// socket and atomics; on() opens and configures the socket (allocation only there).
#pragma once

#include <atomic>

#include "common/chassis_base.h"
#include "rack/core/data_component.h"
#include "rack/devices/can_port.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class ChassisCan final : public ChassisBase {
 public:
  ChassisCan();

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT
  // MOVE, SET_ACTIVE_PILOT, GET_PARAMS: ChassisBase (vy is always 0 here).
  [[nodiscard]] interfaces::ChassisParams chassis_params() const noexcept override;

 private:
  struct Drive {
    uint8_t node = 0;
    int64_t last_heartbeat_ns = 0;
    int64_t started_ns = 0;    // when on() sent NMT start
    bool operational = false;  // a heartbeat said OPERATIONAL since then
    int32_t velocity = 0;      // counts/s (TPDO1)
    int32_t position = 0;      // counts (TPDO1)
    int32_t last_position = 0;
    uint16_t statusword = 0;
    bool have_position = false;
    bool got_tpdo1 = false, got_tpdo2 = false;
  };
  enum class Fault : uint8_t {
    kNone,
    kOpen,
    kSdo,
    kPowerUp,
    kHeartbeat,
    kNmtState,
    kDriveFault,
    kBus,
    kNoPdo,
    kNotOperational
  };

  [[nodiscard]] bool sdo_write(uint8_t node, uint16_t index, uint8_t sub, uint32_t value, uint8_t size) noexcept;
  [[nodiscard]] bool configure(Drive& d) noexcept;
  void handle_frame(const can_frame& f, int64_t now) noexcept;
  void stop_drive(const Drive& d) noexcept;
  [[nodiscard]] HookResult fail(Fault f) noexcept;
  [[nodiscard]] int32_t to_counts(double wheel_mps, bool inverted) const noexcept;

  Parameter& can_;
  Parameter& left_node_;
  Parameter& right_node_;
  Parameter& track_;
  Parameter& counts_per_meter_;
  Parameter& left_inverted_;
  Parameter& right_inverted_;
  Parameter& vx_max_;
  Parameter& omega_max_;
  Parameter& acc_max_;
  Parameter& dec_max_;
  Parameter& watchdog_ms_;
  Parameter& heartbeat_ms_;
  Parameter& heartbeat_timeout_ms_;
  Parameter& sdo_timeout_ms_;
  Parameter& max_missed_syncs_;
  Parameter& boundary_front_;
  Parameter& boundary_back_;
  Parameter& boundary_side_;
  Parameter& safety_margin_;

  devices::CanPort port_;
  Drive drives_[2];  // left, right
  char spec_[128] = {};
  uint32_t missed_syncs_ = 0;

  Velocity target_;  // loop(): the newest MOVE (take_velocity); on() zeroes it
  std::atomic<uint32_t> watchdog_stops_{0};
  bool watchdog_tripped_ = false;  // loop() only
  std::atomic<uint8_t> fault_{0};  // the last Fault (for status and tests)
};

}  // namespace rack::components
