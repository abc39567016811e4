#include "ladar_hokuyo.h"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace rack::components {

namespace scip = devices::scip;
using devices::IoStatus;

LadarHokuyo::LadarHokuyo()
    : DataComponent(DataTaskMode::kPeriodic),
      device_(declare_string(
          "device", "", {.doc = "serial/USB-ACM device (/dev/ttyACM0)", .required = true, .path = PathRole::kDevice})),
      baud_(declare_int("baud", 115200, {.doc = "baud rate (ignored by USB-ACM models)", .min = 1200, .max = 4000000})),
      cluster_(
          declare_int("cluster", 1, {.doc = "steps merged into one beam (1: full resolution)", .min = 1, .max = 99})),
      device_timeout_ms_(declare_float(
          "device_timeout_ms", 500.0,
          {.doc = "ERROR when the device sent no valid scan for this long (also its replies' deadline, plus 0.5 s)",
           .min = 1.0,
           .max = 3.6e6,
           .unit = "ms"})) {
  parameters().add_old_name("timeout_ms", "device_timeout_ms");  // docs/parameters.md
}

void LadarHokuyo::init() {
  parser_ = std::make_unique<scip::Parser>();
  sample_ = std::make_unique<interfaces::LadarData>();
}

bool LadarHokuyo::transact(const char* command, scip::Parser::Event until) noexcept {
  const std::size_t len = std::strlen(command);
  if (port_.write_all(std::span(reinterpret_cast<const uint8_t*>(command), len), 200 * rt::kNsPerMs).status !=
      IoStatus::kOk) {
    return false;
  }
  struct Wait {
    scip::Parser::Event until;
    const char* command;
    bool done = false;
    bool error = false;
  } w{until, command};
  const int64_t deadline = rt::monotonic_ns() + static_cast<int64_t>(device_timeout_ms_.get_float() * 1e6) +
                           rt::kNsPerSec / 2;
  while (!w.done && !w.error) {
    const int64_t left = deadline - rt::monotonic_ns();
    if (left <= 0) return false;
    const devices::IoResult r = port_.read(buffer_, left);
    if (r.status == IoStatus::kTimeout) return false;
    if (r.status != IoStatus::kOk) return false;
    parser_->feed(
        std::span<const uint8_t>(buffer_.data(), r.bytes),
        [](void* user, scip::Parser::Event e, const char cmd[2], const char st[2]) {
          auto* wait = static_cast<Wait*>(user);
          if (cmd[0] != wait->command[0] || cmd[1] != wait->command[1]) return;  // stale output
          if (e == wait->until) wait->done = true;
          else if (e == scip::Parser::Event::kStatus && !(st[0] == '0' && st[1] == '0')) wait->error = true;
        },
        &w);
  }
  return w.done;
}

HookResult LadarHokuyo::on() {
  device_.copy_string(path_, sizeof path_);
  if (!port_.open(path_, static_cast<int>(baud_.get_int()), error_, sizeof error_)) {
    log_error("cannot open the scanner: %s (retrying)", static_cast<const char*>(error_));
    return HookResult::kError;
  }
  // The port registered its descriptor(s) as RT devices when it opened: mode-switch
  // detection allows their I/O in this component's RT tasks.
  parser_->reset();
  // A sensor still streaming from a previous session answers QT after its current scan.
  if (!transact("QT\n", scip::Parser::Event::kStatus) || !transact("PP\n", scip::Parser::Event::kParameters)) {
    port_.close();
    return HookResult::kError;
  }
  const scip::Parameters& p = parser_->parameters();
  if (!p.complete() || (p.amax - p.amin) / static_cast<uint32_t>(cluster_.get_int()) + 1 > interfaces::kLadarMaxBeams) {
    port_.close();
    return HookResult::kError;  // a model this driver cannot represent in LadarData
  }
  char md[32];
  std::snprintf(md, sizeof md, "MD%04u%04u%02u000\n", p.amin, p.amax, static_cast<unsigned>(cluster_.get_int()));
  if (!transact(md, scip::Parser::Event::kStatus)) {
    port_.close();
    return HookResult::kError;
  }
  last_scan_ns_ = rt::monotonic_ns();
  return HookResult::kOk;
}

void LadarHokuyo::off() {
  if (port_.is_open()) {
    static constexpr uint8_t kQt[] = {'Q', 'T', '\n'};  // laser off
    (void)port_.write_all(kQt, 50 * rt::kNsPerMs);
  }
  port_.close();
}

void LadarHokuyo::publish_scan(int64_t stamp_ns) noexcept {
  const scip::Parameters& p = parser_->parameters();
  const scip::Scan& s = parser_->scan();
  interfaces::LadarData& d = *sample_;
  const double step = 2.0 * M_PI / p.ares;
  const uint32_t n = s.count < interfaces::kLadarMaxBeams ? s.count : interfaces::kLadarMaxBeams;
  d.beam_count = n;
  d.start_angle = static_cast<float>((static_cast<double>(s.first_step) - p.afrt) * step);
  d.angle_step = static_cast<float>(step * s.cluster);
  d.min_range = static_cast<float>(p.dmin_mm) * 1e-3F;
  d.max_range = static_cast<float>(p.dmax_mm) * 1e-3F;
  const double rev_ns = 60e9 / p.scan_rpm;
  d.duration_ns = static_cast<int64_t>(rev_ns * (s.last_step - s.first_step) / p.ares);
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t mm = s.range_mm[i];
    // Values below DMIN are error codes (no echo, strong light, ...): no range.
    d.range[i] = (mm < p.dmin_mm || mm > p.dmax_mm) ? 0.0F : static_cast<float>(mm) * 1e-3F;
    d.intensity[i] = 0.0F;
  }
  publish(d, stamp_ns - d.duration_ns);
}

HookResult LadarHokuyo::loop() {
  for (int i = 0; i < 16; ++i) {
    const devices::IoResult r = port_.read(buffer_, 0);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) {  // unplugged: reopen in on()
      log_error("%s: the scanner is gone (unplugged or an I/O error); reopening", static_cast<const char*>(path_));
      return HookResult::kError;
    }
    struct Seen {
      LadarHokuyo* self;
      int64_t stamp;
      bool scan = false;
    } seen{this, r.stamp_ns};
    parser_->feed(
        std::span<const uint8_t>(buffer_.data(), r.bytes),
        [](void* user, scip::Parser::Event e, const char*, const char*) {
          auto* s = static_cast<Seen*>(user);
          if (e != scip::Parser::Event::kScan) return;
          s->self->publish_scan(s->stamp);  // the scan is only valid during the call
          s->scan = true;
        },
        &seen);
    if (seen.scan) last_scan_ns_ = rt::monotonic_ns();
  }
  if (static_cast<double>(rt::monotonic_ns() - last_scan_ns_) > device_timeout_ms_.get_float() * 1e6) {
    log_error("%s: no scan for %.0f ms; reopening", static_cast<const char*>(path_), device_timeout_ms_.get_float());
    return HookResult::kError;
  }
  return HookResult::kOk;
}

}  // namespace rack::components
