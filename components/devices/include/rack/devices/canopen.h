// CANopen (CiA 301) framing and the CiA 402 drive-profile objects the CAN drivers use:
// NMT, expedited SDO, PDOs, SYNC and heartbeat. Frame builders and parsers only; the
// state machines live in the drivers and in the drive simulator.
//
// PDO layout used by RACK-RT's drivers (configured over SDO at on(), as a real
// drive needs; the simulator implements exactly this layout):
//   RPDO1 0x200+node  controlword u16 | target velocity i32 (0x60FF) or
//                     target position i32 (0x607A)          -- event driven
//   RPDO2 0x300+node  profile velocity u32 (0x6081)           -- profile position moves
//   TPDO1 0x180+node  velocity actual i32 (0x606C) | position actual i32 (0x6064)
//   TPDO2 0x280+node  statusword u16 (0x6041)                -- both on every SYNC
//
// Real-time contract: everything here is RT-safe (pure functions on can_frame).
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <cstring>

namespace rack::devices::canopen {

// Function codes (COB-ID = code + node id).
inline constexpr canid_t kNmt = 0x000;
inline constexpr canid_t kSync = 0x080;
inline constexpr canid_t kEmcy = 0x080;  // + node (1..127)
inline constexpr canid_t kTpdo1 = 0x180;
inline constexpr canid_t kRpdo1 = 0x200;
inline constexpr canid_t kTpdo2 = 0x280;
inline constexpr canid_t kRpdo2 = 0x300;
inline constexpr canid_t kSdoTx = 0x580;  // server -> client (responses)
inline constexpr canid_t kSdoRx = 0x600;  // client -> server (requests)
inline constexpr canid_t kHeartbeat = 0x700;

// NMT commands and heartbeat states.
inline constexpr uint8_t kNmtStart = 0x01;
inline constexpr uint8_t kNmtStop = 0x02;
inline constexpr uint8_t kNmtPreOperational = 0x80;
inline constexpr uint8_t kNmtResetNode = 0x81;
inline constexpr uint8_t kStateBootUp = 0x00;
inline constexpr uint8_t kStateStopped = 0x04;
inline constexpr uint8_t kStateOperational = 0x05;
inline constexpr uint8_t kStatePreOperational = 0x7F;

// Objects.
inline constexpr uint16_t kObjHeartbeatTime = 0x1017;  // u16 ms
inline constexpr uint16_t kObjTpdo1Comm = 0x1800;      // sub 2: transmission type (1 = every SYNC)
inline constexpr uint16_t kObjTpdo2Comm = 0x1801;
inline constexpr uint16_t kObjControlword = 0x6040;
inline constexpr uint16_t kObjStatusword = 0x6041;
inline constexpr uint16_t kObjModesOfOperation = 0x6060;  // i8
inline constexpr uint16_t kObjPositionActual = 0x6064;
inline constexpr uint16_t kObjVelocityActual = 0x606C;
inline constexpr uint16_t kObjTargetPosition = 0x607A;
inline constexpr uint16_t kObjProfileVelocity = 0x6081;
inline constexpr uint16_t kObjProfileAcceleration = 0x6083;
inline constexpr uint16_t kObjProfileDeceleration = 0x6084;
inline constexpr uint16_t kObjTargetVelocity = 0x60FF;

inline constexpr int8_t kModeProfilePosition = 1;
inline constexpr int8_t kModeProfileVelocity = 3;

// CiA 402 controlword commands.
inline constexpr uint16_t kCwShutdown = 0x0006;
inline constexpr uint16_t kCwSwitchOn = 0x0007;
inline constexpr uint16_t kCwEnableOperation = 0x000F;
inline constexpr uint16_t kCwQuickStop = 0x0002;
inline constexpr uint16_t kCwDisableVoltage = 0x0000;
inline constexpr uint16_t kCwFaultReset = 0x0080;
inline constexpr uint16_t kCwNewSetPoint = 0x0010;  // profile position: bit 4

// Statusword: state = statusword & mask.
inline constexpr uint16_t kSwStateMask = 0x006F;
inline constexpr uint16_t kSwSwitchOnDisabled = 0x0040;  // mask 0x4F
inline constexpr uint16_t kSwReadyToSwitchOn = 0x0021;
inline constexpr uint16_t kSwSwitchedOn = 0x0023;
inline constexpr uint16_t kSwOperationEnabled = 0x0027;
inline constexpr uint16_t kSwFault = 0x0008;          // bit 3
inline constexpr uint16_t kSwTargetReached = 0x0400;  // bit 10
inline constexpr uint16_t kSwSetPointAck = 0x1000;    // bit 12 (profile position)

// SDO abort codes (a few).
inline constexpr uint32_t kAbortNoObject = 0x06020000;
inline constexpr uint32_t kAbortUnsupported = 0x06010000;
inline constexpr uint32_t kAbortTimeout = 0x05040000;

[[nodiscard]] inline uint16_t get_u16(const uint8_t* p) noexcept { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
[[nodiscard]] inline uint32_t get_u32(const uint8_t* p) noexcept {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}
inline void put_u16(uint8_t* p, uint16_t v) noexcept {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline void put_u32(uint8_t* p, uint32_t v) noexcept {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

[[nodiscard]] inline can_frame nmt(uint8_t command, uint8_t node) noexcept {
  can_frame f{};
  f.can_id = kNmt;
  f.len = 2;
  f.data[0] = command;
  f.data[1] = node;
  return f;
}
[[nodiscard]] inline can_frame sync() noexcept {
  can_frame f{};
  f.can_id = kSync;
  return f;
}
[[nodiscard]] inline can_frame heartbeat(uint8_t node, uint8_t state) noexcept {
  can_frame f{};
  f.can_id = kHeartbeat + node;
  f.len = 1;
  f.data[0] = state;
  return f;
}
// Expedited download (write) of 1, 2 or 4 bytes.
[[nodiscard]] inline can_frame sdo_write(uint8_t node, uint16_t index, uint8_t sub, uint32_t value,
                                         uint8_t size) noexcept {
  can_frame f{};
  f.can_id = kSdoRx + node;
  f.len = 8;
  // ccs=1, expedited, size indicated, n = 4 - size unused bytes.
  f.data[0] = static_cast<uint8_t>(0x23 | ((4 - size) << 2));
  put_u16(&f.data[1], index);
  f.data[3] = sub;
  put_u32(&f.data[4], value);
  return f;
}
// Upload (read) request.
[[nodiscard]] inline can_frame sdo_read(uint8_t node, uint16_t index, uint8_t sub) noexcept {
  can_frame f{};
  f.can_id = kSdoRx + node;
  f.len = 8;
  f.data[0] = 0x40;
  put_u16(&f.data[1], index);
  f.data[3] = sub;
  return f;
}

struct SdoResponse {
  enum class Kind : uint8_t { kNone, kWriteOk, kReadOk, kAbort } kind = Kind::kNone;
  uint16_t index = 0;
  uint8_t sub = 0;
  uint32_t value = 0;  // read value, or the abort code
};
// Parses an SDO response from `node`; kind kNone when the frame is something else.
[[nodiscard]] inline SdoResponse parse_sdo_response(const can_frame& f, uint8_t node) noexcept {
  SdoResponse r;
  if (f.can_id != kSdoTx + node || f.len != 8) return r;
  r.index = get_u16(&f.data[1]);
  r.sub = f.data[3];
  r.value = get_u32(&f.data[4]);
  const uint8_t cmd = f.data[0];
  if (cmd == 0x60) r.kind = SdoResponse::Kind::kWriteOk;
  else if (cmd == 0x80) r.kind = SdoResponse::Kind::kAbort;
  else if ((cmd & 0xE3) == 0x43) r.kind = SdoResponse::Kind::kReadOk;  // expedited upload, size indicated
  return r;
}

[[nodiscard]] inline can_frame rpdo2_profile_velocity(uint8_t node, uint32_t velocity) noexcept {
  can_frame f{};
  f.can_id = kRpdo2 + node;
  f.len = 4;
  put_u32(&f.data[0], velocity);
  return f;
}
[[nodiscard]] inline can_frame rpdo1(uint8_t node, uint16_t controlword, int32_t target) noexcept {
  can_frame f{};
  f.can_id = kRpdo1 + node;
  f.len = 6;
  put_u16(&f.data[0], controlword);
  put_u32(&f.data[2], static_cast<uint32_t>(target));
  return f;
}

}  // namespace rack::devices::canopen
