#include "ladar_sick.h"

#include <cmath>

namespace rack::components {

namespace cola = devices::cola;
using devices::IoStatus;

LadarSick::LadarSick()
    : DataComponent(DataTaskMode::kPeriodic),
      host_(declare_string(
          "host", "",
          {.doc = "scanner IPv4 address (factory default 192.168.0.1)", .required = true, .init_only = true})),
      port_(declare_int("port", 2111, {.doc = "CoLa-A TCP port", .min = 1, .max = 65535, .init_only = true})),
      device_timeout_ms_(declare_float(
          "device_timeout_ms", 500.0,
          {.doc = "ERROR when the scanner sent no valid scan for this long", .min = 1.0, .max = 3.6e6, .unit = "ms"})),
      max_range_(
          declare_float("max_range", 20.0, {.doc = "m, the model's range (LMS111: 20, LMS151: 50)", .min = 0.1})) {
  parameters().add_old_name("timeout_ms", "device_timeout_ms");  // docs/parameters.md
}

void LadarSick::init() {
  parser_ = std::make_unique<cola::Parser>();
  sample_ = std::make_unique<interfaces::LadarData>();
  devices::TcpSensorConfig c;
  c.host = host_.get_string();
  c.port = static_cast<uint16_t>(port_.get_int());
  const std::string start = "\x02sEN LMDscandata 1\x03";  // continuous output after every connect
  c.greeting.assign(start.begin(), start.end());
  link_.open(std::move(c));
  // Connecting and reading block: an executor-owned I/O worker runs the link (not RT).
  add_io_worker(
      "tcp-sensor", [this] { link_.run(); }, [this] { link_.request_stop(); });
  // The port registered its descriptor(s) as RT devices when it opened: mode-switch
  // detection allows their I/O in this component's RT tasks.
}

void LadarSick::cleanup() { link_.close(); }  // the executor has joined the link's worker

HookResult LadarSick::on() {
  if (!link_.connected()) return HookResult::kError;  // the link thread keeps trying
  link_.discard();                                    // what queued while DISABLED is old
  parser_->reset();
  last_scan_ns_ = rt::monotonic_ns();
  return HookResult::kOk;
}

void LadarSick::off() {}

void LadarSick::publish_scan(int64_t stamp_ns) noexcept {
  const cola::Scan& s = parser_->scan();
  interfaces::LadarData& d = *sample_;
  const uint32_t n = s.count < interfaces::kLadarMaxBeams ? s.count : interfaces::kLadarMaxBeams;
  constexpr double kDeg = M_PI / 180.0;
  d.beam_count = n;
  d.start_angle = static_cast<float>((s.start_angle_deg - 90.0) * kDeg);
  d.angle_step = static_cast<float>(s.step_deg * kDeg);
  d.min_range = 0.05F;
  d.max_range = static_cast<float>(max_range_.get_float());
  const double period_ns = s.scan_frequency_centihz > 0 ? 1e11 / s.scan_frequency_centihz : 0.0;
  // The mirror turns 360 deg per period; the scan covers its angular range of it.
  d.duration_ns = static_cast<int64_t>(period_ns * (s.step_deg * s.count) / 360.0);
  for (uint32_t i = 0; i < n; ++i) {
    const float r = s.range_m[i];
    d.range[i] = (r < d.min_range || r > d.max_range) ? 0.0F : r;
    d.intensity[i] = s.has_rssi ? s.rssi[i] : 0.0F;
  }
  publish(d, stamp_ns - static_cast<int64_t>(period_ns));
}

HookResult LadarSick::loop() {
  for (int i = 0; i < 16; ++i) {
    const devices::IoResult r = link_.read(buffer_, 0);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) {  // the connection was lost: the link reconnects
      parser_->reset();
      return HookResult::kError;
    }
    struct Seen {
      LadarSick* self;
      int64_t stamp;
      bool scan = false;
    } seen{this, r.stamp_ns};
    parser_->feed(
        std::span<const uint8_t>(buffer_.data(), r.bytes),
        [](void* user, const char*, std::size_t, bool is_scan) {
          auto* s = static_cast<Seen*>(user);
          if (!is_scan) return;
          s->self->publish_scan(s->stamp);
          s->scan = true;
        },
        &seen);
    if (seen.scan) last_scan_ns_ = rt::monotonic_ns();
  }
  if (static_cast<double>(rt::monotonic_ns() - last_scan_ns_) > device_timeout_ms_.get_float() * 1e6) {
    link_.request_reconnect();  // a connected but mute scanner: start over
    return HookResult::kError;
  }
  return HookResult::kOk;
}

}  // namespace rack::components
