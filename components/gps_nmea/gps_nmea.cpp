#include "gps_nmea.h"

#include "rack/devices/utm.h"

namespace rack::components {

using devices::IoStatus;
using devices::NmeaParser;

GpsNmea::GpsNmea()
    : DataComponent(DataTaskMode::kPeriodic),
      device_(declare_string(
          "device", "",
          {.doc = "serial device of the receiver (/dev/ttyUSB0)", .required = true, .path = PathRole::kDevice})),
      baud_(declare_int("baud", 9600,
                        {.doc = "baud rate (4800, 9600, 38400, 115200, ...)", .min = 1200, .max = 4000000})),
      device_timeout_ms_(declare_float("device_timeout_ms", 2000.0,
                                       {.doc = "ERROR when the receiver sent no valid position sentence for this long",
                                        .min = 1.0,
                                        .max = 3.6e6,
                                        .unit = "ms"})),
      origin_lat_(declare_float("origin_latitude_deg", 0.0,
                                {.doc = "local frame origin (0/0: the first fix)", .min = -90.0, .max = 90.0})),
      origin_lon_(declare_float("origin_longitude_deg", 0.0,
                                {.doc = "local frame origin (0/0: the first fix)", .min = -180.0, .max = 180.0})) {
  parameters().add_old_name("timeout_ms", "device_timeout_ms");  // docs/parameters.md
}

HookResult GpsNmea::on() {
  device_.copy_string(path_, sizeof path_);
  // The port registered its descriptor(s) as RT devices when it opened: mode-switch
  // detection allows their I/O in this component's RT tasks.
  if (!port_.open(path_, static_cast<int>(baud_.get_int()), error_, sizeof error_)) {
    log_error("cannot open the GPS receiver: %s (retrying)", static_cast<const char*>(error_));
    return HookResult::kError;
  }
  parser_.reset();  // a partial sentence from before is not this session's; counters keep counting
  last_position_ns_ = rt::monotonic_ns();
  have_origin_ = false;
  const double olat = origin_lat_.get_float(), olon = origin_lon_.get_float();
  if (olat != 0.0 || olon != 0.0) {
    const devices::UtmPoint o = devices::wgs84_to_utm(olat, olon);
    origin_zone_ = o.zone;
    origin_e_ = o.easting;
    origin_n_ = o.northing;
    have_origin_ = true;
  }
  return HookResult::kOk;
}

void GpsNmea::off() { port_.close(); }

void GpsNmea::fill(interfaces::GpsData& d) noexcept {
  const devices::NmeaFix& f = parser_.fix();
  d.latitude_deg = f.latitude_deg;
  d.longitude_deg = f.longitude_deg;
  d.altitude = f.altitude_m;
  d.speed = f.speed_mps;
  d.course_deg = f.course_deg;
  d.hdop = f.hdop;
  d.pdop = f.pdop;
  d.vdop = f.vdop;
  d.utc_ns = f.utc_ns;
  d.fix_quality = f.quality;
  d.fix_mode = f.mode;
  d.satellites = f.satellites;
  const auto& c = parser_.counters();
  d.sentences = static_cast<uint32_t>(c.sentences);
  d.checksum_errors = static_cast<uint32_t>(c.checksum_errors);
  d.malformed = static_cast<uint32_t>(c.malformed + c.overlong);
  d.garbage_bytes = static_cast<uint32_t>(c.garbage_bytes);
  const bool fixed = f.quality != interfaces::kGpsFixNone || f.rmc_valid;
  if (!fixed) return;
  const devices::UtmPoint u = devices::wgs84_to_utm(f.latitude_deg, f.longitude_deg);
  d.utm_easting = u.easting;
  d.utm_northing = u.northing;
  d.utm_zone = static_cast<uint32_t>(u.zone);
  d.utm_north = u.north ? 1 : 0;
  if (!have_origin_) {
    origin_zone_ = u.zone;
    origin_e_ = u.easting;
    origin_n_ = u.northing;
    have_origin_ = true;
  }
  // The local frame stays in the origin's zone, so it does not jump at a zone border.
  const devices::UtmPoint l = u.zone == origin_zone_
                                  ? u
                                  : devices::wgs84_to_utm(f.latitude_deg, f.longitude_deg, origin_zone_);
  d.x = l.easting - origin_e_;
  d.y = l.northing - origin_n_;
}

HookResult GpsNmea::loop() {
  bool position = false;
  int64_t stamp = 0;
  // Bounded: at 115200 baud a 20 ms cycle brings ~230 bytes; 16 reads of 512 is plenty.
  for (int i = 0; i < 16; ++i) {
    const devices::IoResult r = port_.read(buffer_, 0);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) {  // unplugged or I/O error: reopen in on()
      log_error("%s: the device is gone (unplugged or an I/O error); reopening", static_cast<const char*>(path_));
      return HookResult::kError;
    }
    struct Seen {
      bool position = false;
    } seen;
    parser_.feed(
        std::span<const uint8_t>(buffer_.data(), r.bytes),
        [](void* user, NmeaParser::Sentence s) {
          if (s == NmeaParser::Sentence::kGga || s == NmeaParser::Sentence::kRmc) {
            static_cast<Seen*>(user)->position = true;
          }
        },
        &seen);
    if (seen.position) {
      position = true;
      stamp = r.stamp_ns;
    }
  }
  const int64_t now = rt::monotonic_ns();
  if (position) {
    last_position_ns_ = now;
    interfaces::GpsData d;
    fill(d);
    publish(d, stamp);
    return HookResult::kOk;
  }
  if (static_cast<double>(now - last_position_ns_) > device_timeout_ms_.get_float() * 1e6) {
    log_error("%s: no position sentence for %.0f ms; reopening", static_cast<const char*>(path_),
              device_timeout_ms_.get_float());
    return HookResult::kError;
  }
  return HookResult::kOk;
}

}  // namespace rack::components
