// LadarHokuyo (class Ladar): a Hokuyo URG/UTM laser scanner speaking SCIP 2.0 over
// serial or USB-ACM (/dev/ttyACM0).
//
// on(): stops any running output (QT), reads the sensor's parameters (PP: range
// limits, angular resolution, front step, scan rate), and starts continuous output
// (MD, 3-character encoding, over the whole measurable range with `cluster` steps
// per beam). loop() (periodic, shorter than the scan period) reads what arrived and
// publishes each complete scan as LadarData: ranges in metres (0 where the sensor
// reported an error code: no echo, too near, too bright), the scan's start time
// (the read time minus the scan's duration), angles counter-clockwise with 0 ahead.
//
// Bad input: lines with wrong checksums, garbage and truncated responses are
// counted and dropped (never a partial scan). No scan for device_timeout_ms, or a device
// that disappears, puts the component in ERROR; on() retries and reopens it.
//
// Real-time contract: loop() does non-blocking read()s on the open tty and parsing
// into fixed buffers; on() opens the device and waits (bounded) for its answers.
#pragma once

#include <array>

#include "rack/core/data_component.h"
#include "rack/devices/scip.h"
#include "rack/devices/serial_port.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class LadarHokuyo final : public DataComponent<interfaces::LadarData> {
 public:
  LadarHokuyo();

 protected:
  void init() override;
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT

 private:
  // Sends a command and feeds the parser until `until` arrives for it (bounded).
  [[nodiscard]] bool transact(const char* command, devices::scip::Parser::Event until) noexcept;
  void publish_scan(int64_t stamp_ns) noexcept;

  Parameter& device_;
  Parameter& baud_;
  Parameter& cluster_;
  Parameter& device_timeout_ms_;  // formerly timeout_ms
  devices::SerialPort port_;
  std::unique_ptr<devices::scip::Parser> parser_;  // ~15 KB: allocated in init()
  std::unique_ptr<interfaces::LadarData> sample_;  // ~9 KB: allocated in init()
  std::array<uint8_t, 1024> buffer_{};
  char path_[256] = {};
  char error_[256] = {};
  int64_t last_scan_ns_ = 0;
};

}  // namespace rack::components
