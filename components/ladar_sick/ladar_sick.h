// LadarSick (class Ladar): a SICK LMS1xx (also LMS5xx, TiM5xx) over TCP, CoLa-A.
//
// The connection is kept by a non-RT link (rack/devices/tcp_sensor_link.h) that runs
// in an executor-owned I/O worker declared in init(): it connects to host:port, sends
// "sEN LMDscandata 1" (continuous output) after every connect, and reconnects with
// back-off when the scanner goes away. loop() (periodic, shorter than the scan period) takes the bytes the thread
// buffered, parses LMDscandata telegrams and publishes each scan as LadarData:
// DIST1 in metres (0: no echo), RSSI1 as intensity, angles turned from SICK's frame
// (90 deg ahead) into the robot's (0 ahead, counter-clockwise), the sample time the
// receive time minus one scan period.
//
// Bad input: truncated or malformed telegrams and garbage are counted and dropped.
// A lost connection or no scan for device_timeout_ms puts the component in ERROR (and asks
// the link to reconnect); on() succeeds again once the link is connected.
//
// Real-time contract: loop() only copies from the link's ring (eventfd + memcpy) and
// parses into fixed buffers. on() and off() only look at the link's state.
#pragma once

#include <array>
#include <memory>

#include "rack/core/data_component.h"
#include "rack/devices/cola.h"
#include "rack/devices/tcp_sensor_link.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class LadarSick final : public DataComponent<interfaces::LadarData> {
 public:
  LadarSick();

 protected:
  void init() override;
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT
  void cleanup() override;

 private:
  void publish_scan(int64_t stamp_ns) noexcept;

  Parameter& host_;
  Parameter& port_;
  Parameter& device_timeout_ms_;  // formerly timeout_ms
  Parameter& max_range_;
  devices::TcpSensorLink link_;
  std::unique_ptr<devices::cola::Parser> parser_;  // ~45 KB: allocated in init()
  std::unique_ptr<interfaces::LadarData> sample_;  // ~9 KB: allocated in init()
  std::array<uint8_t, 8192> buffer_{};
  int64_t last_scan_ns_ = 0;
};

}  // namespace rack::components
