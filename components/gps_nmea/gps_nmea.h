// GpsNmea (class Gps): a GNSS receiver speaking NMEA 0183 over a serial port (UART,
// USB-serial, USB-ACM). Reads GGA, RMC, GSA and VTG, checks every checksum, and
// publishes one GpsData per loop in which a position sentence (GGA or RMC) arrived:
// WGS84 position, fix, satellites, DOPs, speed and course, UTM, and a local frame
// (x east, y north of an origin) for the rest of the robot.
//
// Parameters (rackd --list-classes prints them):
//   device         the serial device ("/dev/ttyUSB0"; a udev symlink is better)
//   baud           4800 .. 921600 (receivers: 4800 or 9600 by default, u-blox 9600)
//   device_timeout_ms   no valid position sentence for this long: ERROR (then on()
//                  retries, reopening the device: a replugged receiver comes back by
//                  itself); formerly timeout_ms
//   origin_latitude_deg / origin_longitude_deg   the local frame's origin; both 0:
//                  the first fix after ON becomes the origin
//
// Bad input: wrong checksums, malformed sentences, line noise and unknown sentences
// are counted (GpsData's counters) and change nothing. A device that disappears
// (EIO/hang-up) or falls silent puts the component in ERROR.
//
// Data task: periodic (period_ms in the host file, e.g. 20 ms); each cycle reads
// what the port has without waiting. Real-time contract: loop() does only
// non-blocking read()s on the open tty and arithmetic; on() opens the device.
#pragma once

#include <array>

#include "rack/core/data_component.h"
#include "rack/devices/nmea.h"
#include "rack/devices/serial_port.h"
#include "gps_nmea_types.h"
#include "rack/interfaces/devices.h"

namespace rack::components {

class GpsNmea final : public DataComponent<interfaces::GpsData> {
 public:
  GpsNmea();

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT

 private:
  void fill(interfaces::GpsData& d) noexcept;

  Parameter& device_;
  Parameter& baud_;
  Parameter& device_timeout_ms_;  // formerly timeout_ms
  Parameter& origin_lat_;
  Parameter& origin_lon_;
  devices::SerialPort port_;
  devices::NmeaParser parser_;
  std::array<uint8_t, 512> buffer_{};
  char path_[256] = {};
  char error_[256] = {};
  int64_t last_position_ns_ = 0;  // monotonic time of the last GGA/RMC
  bool have_origin_ = false;
  int origin_zone_ = 0;
  double origin_e_ = 0.0, origin_n_ = 0.0;
};

}  // namespace rack::components
