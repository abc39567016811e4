// ServoDriveCan (class ServoDrive): one axis on a CANopen CiA 402 drive in profile
// position mode, over SocketCAN or the drive simulator's socket ("unix:/path").
//
// on(): NMT pre-operational, SDO set-up (mode 1 = profile position, acceleration,
// heartbeat, TPDOs on SYNC), CiA 402 power-up, NMT start. loop() (periodic): RPDO1
// (controlword, target position) with the new-set-point handshake (bit 4 until the
// drive acknowledges with statusword bit 12), RPDO2 (profile velocity) per move, SYNC,
// TPDO1/TPDO2; publishes ServoDriveData; sends POSITION_REACHED to whoever asked for
// the move when the drive sets "target reached". Heartbeat monitoring as ChassisCan: a
// silent or faulted drive is ERROR (and is quick-stopped).
//
// Commands: HOME, MOVE_POS, MOVE_VEL (rack/interfaces/devices.h).
// Real-time contract: loop() and command() use send/recvmsg/ppoll on the open CAN
// socket and atomics; on() opens and configures it.
#pragma once

#include <atomic>

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/devices/can_port.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

class ServoDriveCan final : public DataComponent<interfaces::ServoDriveData> {
 public:
  ServoDriveCan();

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  [[nodiscard]] bool request_move(double target_unit, double velocity_unit, uint32_t requester) noexcept;
  [[nodiscard]] double to_unit(int32_t counts) const noexcept;

  Parameter& can_;
  Parameter& node_;
  Parameter& counts_per_unit_;
  Parameter& max_velocity_;
  Parameter& acceleration_;
  Parameter& position_min_;
  Parameter& position_max_;
  Parameter& home_position_;
  Parameter& heartbeat_ms_;
  Parameter& heartbeat_timeout_ms_;
  Parameter& sdo_timeout_ms_;

  devices::CanPort port_;
  char spec_[128] = {};
  // The ERROR's reason for a CAN port that failed while `doing`, and kError. RT-safe.
  HookResult port_failed(const char* doing) noexcept;
  uint8_t node_id_ = 1;

  // Data task only.
  int32_t position_ = 0, velocity_ = 0;
  uint16_t statusword_ = 0;
  bool got_tpdo1_ = false, got_tpdo2_ = false;
  int64_t last_heartbeat_ns_ = 0;
  bool nmt_left_operational_ = false;
  // A heartbeat said NMT operational since on(): a pre-operational one before that is the
  // drive's start-up (sent before it took on()'s NMT start), not a fault.
  bool seen_operational_ = false;
  int64_t on_ns_ = 0;
  bool setpoint_high_ = false;  // bit 4 raised, waiting for the acknowledgement
  bool moving_ = false;         // a set-point taken, not yet reached
  int32_t target_counts_ = 0;
  uint32_t notify_ = 0;  // who gets POSITION_REACHED
  interfaces::ServoDriveData out_{};

  // Command task -> data task: the newest move asked for.
  struct Move {
    int32_t target = 0;      // counts
    uint32_t velocity = 0;   // counts/s
    uint32_t requester = 0;  // who gets POSITION_REACHED
  };
  Handoff<Move> move_;
  // Position of the drive (counts) that is home; written by HOME (command task),
  // read by loop(). Relaxed: a single value.
  std::atomic<int32_t> home_offset_{0};
  std::atomic<bool> homed_{false};
  std::atomic<int32_t> last_position_{0};  // loop() -> HOME/MOVE_VEL (relaxed: a reading)
  std::atomic<uint32_t> moves_{0};
};

}  // namespace rack::components
