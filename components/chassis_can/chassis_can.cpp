#include "chassis_can.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "rack/devices/canopen.h"
#include "rack/devices/canopen_client.h"

namespace rack::components {

namespace co = devices::canopen;
using devices::IoStatus;
using interfaces::ChassisData;

ChassisCan::ChassisCan()
    : ChassisBase(DataTaskMode::kPeriodic),
      can_(declare_string("can", "",
                          {.doc = "CAN interface (can0, vcan0) or unix:/path of a drive simulator", .required = true})),
      left_node_(declare_int("left_node", 1, {.doc = "CANopen node id of the left drive", .min = 1, .max = 127})),
      right_node_(declare_int("right_node", 2, {.doc = "CANopen node id of the right drive", .min = 1, .max = 127})),
      track_(declare_float("track_width", 0.5, {.doc = "m between the wheel contact points", .min = 0.01})),
      counts_per_meter_(
          declare_float("counts_per_meter", 10000.0,
                        {.doc = "drive position units per metre of wheel travel (gear, encoder)", .min = 1e-6})),
      left_inverted_(declare_bool("left_inverted", false, {.doc = "left motor counts backwards"})),
      right_inverted_(declare_bool("right_inverted", false, {.doc = "right motor counts backwards (mirrored mount)"})),
      vx_max_(declare_float("vx_max", 1.0, {.doc = "m/s, MOVE is clamped to this", .min = 0.0})),
      omega_max_(declare_float("omega_max", 1.5, {.doc = "rad/s, MOVE is clamped to this", .min = 0.0})),
      acc_max_(declare_float("acc_max", 1.0, {.doc = "m/s^2, the drives' profile acceleration", .min = 0.001})),
      dec_max_(declare_float("dec_max", 2.0, {.doc = "m/s^2, the drives' profile deceleration", .min = 0.001})),
      watchdog_ms_(declare_float("watchdog_ms", 500.0,
                                 {.doc = "stop when no MOVE came for this long", .min = 1.0, .unit = "ms"})),
      heartbeat_ms_(declare_float("heartbeat_ms", 100.0,
                                  {.doc = "drive heartbeat producer time", .min = 1, .max = 65535, .unit = "ms"})),
      heartbeat_timeout_ms_(declare_float("heartbeat_timeout_ms", 350.0,
                                          {.doc = "a drive silent this long: ERROR, the other stops", .min = 1.0})),
      sdo_timeout_ms_(declare_float("sdo_timeout_ms", 100.0,
                                    {.doc = "wait for each SDO answer in on()", .min = 1.0, .unit = "ms"})),
      max_missed_syncs_(declare_int("max_missed_syncs", 10,
                                    {.doc = "consecutive cycles without both drives' TPDOs before ERROR", .min = 1})),
      boundary_front_(declare_float("boundary_front", 0.3, {.doc = "m, outline ahead of the axle centre"})),
      boundary_back_(declare_float("boundary_back", 0.3, {.doc = "m, outline behind the axle centre"})),
      boundary_side_(declare_float("boundary_side", 0.3, {.doc = "m, outline to each side"})),
      safety_margin_(declare_float("safety_margin", 0.1, {.doc = "m kept free around the outline"})) {}

HookResult ChassisCan::fail(Fault f) noexcept {
  fault_.store(static_cast<uint8_t>(f), std::memory_order_relaxed);
  const char* what = "unknown fault";
  switch (f) {
    case Fault::kNone: what = "no fault"; break;
    case Fault::kOpen: what = "cannot open the CAN interface or set its filters"; break;
    case Fault::kSdo: what = "a drive did not answer its SDO configuration"; break;
    case Fault::kPowerUp: what = "a drive did not reach OPERATION ENABLED"; break;
    case Fault::kHeartbeat: what = "a drive's heartbeat stopped: the other drive was stopped"; break;
    case Fault::kNmtState: what = "a drive left the NMT state OPERATIONAL"; break;
    case Fault::kDriveFault: what = "a drive reports a fault (statusword)"; break;
    case Fault::kBus: what = "CAN bus error (bus-off or the interface is gone)"; break;
    case Fault::kNoPdo: what = "no TPDO from a drive within half a period"; break;
    case Fault::kNotOperational:
      what = "a drive did not report the NMT state OPERATIONAL within heartbeat_timeout_ms of the start";
      break;
  }
  if (f != Fault::kOpen) set_error_reason(what);  // kOpen: on() gave the port's own words
  log_error("chassis fault: %s (%s); retrying after the back-off", what, static_cast<const char*>(spec_));
  return HookResult::kError;
}

bool ChassisCan::sdo_write(uint8_t node, uint16_t index, uint8_t sub, uint32_t value, uint8_t size) noexcept {
  return co::sdo_write_wait(port_, node, index, sub, value, size,
                            static_cast<int64_t>(sdo_timeout_ms_.get_float() * 1e6)) == co::SdoResult::kOk;
}

bool ChassisCan::configure(Drive& d) noexcept {
  const double cpm = counts_per_meter_.get_float();
  const auto acc = static_cast<uint32_t>(std::lround(acc_max_.get_float() * cpm));
  const auto dec = static_cast<uint32_t>(std::lround(dec_max_.get_float() * cpm));
  if (port_.send(co::nmt(co::kNmtPreOperational, d.node)).status != IoStatus::kOk) return false;
  return sdo_write(d.node, co::kObjModesOfOperation, 0, static_cast<uint8_t>(co::kModeProfileVelocity), 1) &&
         sdo_write(d.node, co::kObjTargetVelocity, 0, 0, 4) &&
         sdo_write(d.node, co::kObjProfileAcceleration, 0, acc, 4) &&
         sdo_write(d.node, co::kObjProfileDeceleration, 0, dec, 4) &&
         sdo_write(d.node, co::kObjHeartbeatTime, 0, static_cast<uint32_t>(std::lround(heartbeat_ms_.get_float())),
                   2) &&
         sdo_write(d.node, co::kObjTpdo1Comm, 2, 1, 1) &&  // TPDO1 on every SYNC
         sdo_write(d.node, co::kObjTpdo2Comm, 2, 1, 1);    // TPDO2 on every SYNC
}

HookResult ChassisCan::on() {
  can_.copy_string(spec_, sizeof spec_);
  drives_[0] = Drive{};
  drives_[1] = Drive{};
  drives_[0].node = static_cast<uint8_t>(left_node_.get_int());
  drives_[1].node = static_cast<uint8_t>(right_node_.get_int());
  // A missing bus (no interface, no simulator) fails here every retry: the error text
  // goes into a fixed buffer (no allocation in the command task, failures included)
  // and becomes the ERROR's reason.
  devices::CanError error;
  if (!port_.open(spec_, error)) {
    set_error_reason(error.text);
    return fail(Fault::kOpen);
  }
  // The port registered its descriptor(s) as RT devices when it opened: mode-switch
  // detection allows their I/O in this component's RT tasks.
  // Only what this driver listens to: SDO answers, TPDO1/2 and heartbeats of its drives.
  can_filter filters[8];
  std::size_t n = 0;
  for (const Drive& d : drives_) {
    for (const canid_t base : {co::kSdoTx, co::kTpdo1, co::kTpdo2, co::kHeartbeat}) {
      filters[n++] = can_filter{base + d.node, CAN_SFF_MASK};
    }
  }
  if (!port_.set_filters(std::span<const can_filter>(filters, n), error)) {
    set_error_reason(error.text);
    return fail(Fault::kOpen);
  }
  for (Drive& d : drives_) {
    if (!configure(d)) return fail(Fault::kSdo);
  }
  for (Drive& d : drives_) {
    if (!co::power_up(port_, d.node, static_cast<int64_t>(sdo_timeout_ms_.get_float() * 1e6))) {
      return fail(Fault::kPowerUp);
    }
  }
  for (Drive& d : drives_) {
    if (port_.send(co::nmt(co::kNmtStart, d.node)).status != IoStatus::kOk) return fail(Fault::kBus);
    d.last_heartbeat_ns = rt::monotonic_ns();
    d.started_ns = d.last_heartbeat_ns;
    d.operational = false;
  }
  command_velocity(Velocity{});  // the data task is idle: its target too
  target_ = Velocity{};
  reset_pilot();  // a chassis switched on has no driver until one sets itself active
  watchdog_stops_.store(0, std::memory_order_relaxed);
  watchdog_tripped_ = true;  // stopped until the first MOVE
  missed_syncs_ = 0;
  fault_.store(0, std::memory_order_relaxed);
  return HookResult::kOk;
}

void ChassisCan::stop_drive(const Drive& d) noexcept {
  (void)port_.send(co::rpdo1(d.node, co::kCwEnableOperation, 0));
  (void)port_.send(co::rpdo1(d.node, co::kCwQuickStop, 0));
}

void ChassisCan::off() {
  if (port_.is_open()) {
    for (const Drive& d : drives_) {
      stop_drive(d);
      (void)port_.send(co::rpdo1(d.node, co::kCwShutdown, 0));  // power stage off
    }
  }
  port_.close();
}

int32_t ChassisCan::to_counts(double wheel_mps, bool inverted) const noexcept {
  const double c = wheel_mps * counts_per_meter_.get_float();
  return static_cast<int32_t>(std::lround(inverted ? -c : c));
}

void ChassisCan::handle_frame(const can_frame& f, int64_t now) noexcept {
  if ((f.can_id & CAN_ERR_FLAG) != 0) return;  // CanPort tracked the bus state
  const canid_t id = f.can_id & CAN_SFF_MASK;
  for (Drive& d : drives_) {
    if (id == co::kHeartbeat + d.node && f.len >= 1) {
      d.last_heartbeat_ns = now;
      // A heartbeat sent before the drive took the NMT start may still be on its way
      // (or queued in the socket): only leaving OPERATIONAL once reached is a fault.
      if (f.data[0] == co::kStateOperational) {
        d.operational = true;
      } else if (d.operational) {
        fault_.store(static_cast<uint8_t>(Fault::kNmtState));
      }
    } else if (id == co::kTpdo1 + d.node && f.len == 8) {
      d.velocity = static_cast<int32_t>(co::get_u32(&f.data[0]));
      d.position = static_cast<int32_t>(co::get_u32(&f.data[4]));
      d.got_tpdo1 = true;
    } else if (id == co::kTpdo2 + d.node && f.len >= 2) {
      d.statusword = co::get_u16(&f.data[0]);
      d.got_tpdo2 = true;
    }
  }
}

HookResult ChassisCan::loop() {
  const int64_t now = rt::monotonic_ns();
  // Command watchdog.
  (void)take_velocity(target_);
  double vx = target_.vx;
  double omega = target_.omega;
  const auto watchdog_ns = static_cast<int64_t>(watchdog_ms_.get_float() * 1e6);
  if (now - last_move_ns() > watchdog_ns) {
    if (!watchdog_tripped_ && (vx != 0.0 || omega != 0.0)) {
      watchdog_stops_.fetch_add(1, std::memory_order_relaxed);
    }
    watchdog_tripped_ = true;
    vx = omega = 0.0;
  } else {
    watchdog_tripped_ = false;
  }
  const double half = 0.5 * track_.get_float();
  Drive& left = drives_[0];
  Drive& right = drives_[1];
  const int32_t tl = to_counts(vx - omega * half, left_inverted_.get_bool());
  const int32_t tr = to_counts(vx + omega * half, right_inverted_.get_bool());
  // Frames still queued answer the previous SYNC (a drive that was late): take them
  // now, so that what arrives after this SYNC belongs to it. Late increments are not
  // lost, only counted one cycle later: each wheel's odometry uses its own last reading.
  for (int i = 0; i < 16; ++i) {
    can_frame f{};
    const devices::IoResult r = port_.receive(f, 0);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) return fail(Fault::kBus);
    handle_frame(f, rt::monotonic_ns());
  }
  for (Drive& d : drives_) d.got_tpdo1 = d.got_tpdo2 = false;
  if (port_.send(co::rpdo1(left.node, co::kCwEnableOperation, tl)).status == IoStatus::kClosed ||
      port_.send(co::rpdo1(right.node, co::kCwEnableOperation, tr)).status == IoStatus::kClosed ||
      port_.send(co::sync()).status == IoStatus::kClosed) {
    return fail(Fault::kBus);
  }
  // Collect both drives' TPDOs within half a period (heartbeats come in between).
  const int64_t deadline = now + period_ns() / 2;
  while (!(left.got_tpdo1 && left.got_tpdo2 && right.got_tpdo1 && right.got_tpdo2)) {
    const int64_t wait = deadline - rt::monotonic_ns();
    if (wait <= 0) break;
    can_frame f{};
    const devices::IoResult r = port_.receive(f, wait);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) return fail(Fault::kBus);
    handle_frame(f, rt::monotonic_ns());
  }
  // Safety checks: a silent drive, a drive that left OPERATIONAL or faulted.
  const auto hb_timeout = static_cast<int64_t>(heartbeat_timeout_ms_.get_float() * 1e6);
  const int64_t t = rt::monotonic_ns();
  for (int i = 0; i < 2; ++i) {
    const Drive& d = drives_[i];
    const bool silent = t - d.last_heartbeat_ns > hb_timeout;
    const bool faulted = d.got_tpdo2 && ((d.statusword & co::kSwFault) != 0 ||
                                         (d.statusword & co::kSwStateMask) != co::kSwOperationEnabled);
    const bool left_operational = fault_.load(std::memory_order_relaxed) == static_cast<uint8_t>(Fault::kNmtState);
    const bool never_operational = !d.operational && t - d.started_ns > hb_timeout;
    if (silent || faulted || left_operational || never_operational) {
      stop_drive(drives_[1 - i]);  // the other drive must not keep turning the robot
      stop_drive(d);
      return fail(silent             ? Fault::kHeartbeat
                  : faulted          ? Fault::kDriveFault
                  : left_operational ? Fault::kNmtState
                                     : Fault::kNotOperational);
    }
  }
  const bool complete = left.got_tpdo1 && right.got_tpdo1;
  if (!complete) {
    if (++missed_syncs_ >= static_cast<uint32_t>(max_missed_syncs_.get_int())) {
      for (const Drive& d : drives_) stop_drive(d);
      return fail(Fault::kNoPdo);
    }
    return HookResult::kOk;  // one late cycle: publish nothing rather than a wrong increment
  }
  missed_syncs_ = 0;
  const double cpm = counts_per_meter_.get_float();
  const double sl = left_inverted_.get_bool() ? -1.0 : 1.0;
  const double sr = right_inverted_.get_bool() ? -1.0 : 1.0;
  double dl = 0.0, dr = 0.0;
  if (left.have_position && right.have_position) {
    // int32 difference wraps correctly across the counter's overflow.
    dl = sl * static_cast<int32_t>(static_cast<uint32_t>(left.position) - static_cast<uint32_t>(left.last_position)) /
         cpm;
    dr = sr * static_cast<int32_t>(static_cast<uint32_t>(right.position) - static_cast<uint32_t>(right.last_position)) /
         cpm;
  }
  left.last_position = left.position;
  right.last_position = right.position;
  left.have_position = right.have_position = true;
  ChassisData out;
  const double dphi = (dr - dl) / track_.get_float();
  const double ds = 0.5 * (dl + dr);
  // Arc approximation at the mid-angle: exact for constant curvature to second order.
  out.delta_x = ds * std::cos(0.5 * dphi);
  out.delta_y = ds * std::sin(0.5 * dphi);
  out.delta_phi = dphi;
  const double vl = sl * left.velocity / cpm, vr = sr * right.velocity / cpm;
  out.vx = 0.5 * (vl + vr);
  out.omega = (vr - vl) / track_.get_float();
  out.active_pilot = active_pilot();
  out.watchdog_stops = watchdog_stops_.load(std::memory_order_relaxed);
  publish(out, rt::host_time_ns());
  return HookResult::kOk;
}

interfaces::ChassisParams ChassisCan::chassis_params() const noexcept {
  interfaces::ChassisParams p;
  p.vx_max = vx_max_.get_float();
  p.vx_min = 0.0;
  p.omega_max = omega_max_.get_float();
  p.acc_max = acc_max_.get_float();
  p.dec_max = dec_max_.get_float();
  p.boundary_front = boundary_front_.get_float();
  p.boundary_back = boundary_back_.get_float();
  p.boundary_left = boundary_side_.get_float();
  p.boundary_right = boundary_side_.get_float();
  p.safety_margin = safety_margin_.get_float();
  p.watchdog_ns = static_cast<int64_t>(watchdog_ms_.get_float() * 1e6);
  return p;
}

}  // namespace rack::components
