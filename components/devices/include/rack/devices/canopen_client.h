// Blocking-with-timeout CANopen client transfers over a CanPort, for drivers' on():
// expedited SDO write/read that wait for the matching answer (other frames are
// skipped) or give up after a timeout.
//
// Real-time contract: RT-safe (CanPort send/receive, bounded by the timeout); meant for
// on() (the command task), while the data task is not using the port.
#pragma once

#include <cstdint>

#include "rack/devices/can_port.h"
#include "rack/devices/canopen.h"

namespace rack::devices::canopen {

enum class SdoResult : uint8_t { kOk, kAbort, kTimeout, kBusError };
[[nodiscard]] const char* describe(SdoResult r) noexcept;

[[nodiscard]] SdoResult sdo_write_wait(CanPort& port, uint8_t node, uint16_t index, uint8_t sub, uint32_t value,
                                       uint8_t size, int64_t timeout_ns) noexcept;
[[nodiscard]] SdoResult sdo_read_wait(CanPort& port, uint8_t node, uint16_t index, uint8_t sub, uint32_t& value,
                                      int64_t timeout_ns) noexcept;
// The CiA 402 power-up: shutdown, switch on, enable operation, then checks the
// statusword says OPERATION ENABLED. false on any failure.
[[nodiscard]] bool power_up(CanPort& port, uint8_t node, int64_t timeout_ns) noexcept;

}  // namespace rack::devices::canopen
