#include "servo_drive_can.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "rack/devices/canopen.h"
#include "rack/devices/canopen_client.h"

namespace rack::components {

namespace co = devices::canopen;
using devices::IoStatus;

ServoDriveCan::ServoDriveCan()
    : DataComponent(DataTaskMode::kPeriodic),
      can_(declare_string("can", "",
                          {.doc = "CAN interface (can0) or unix:/path of a drive simulator", .required = true})),
      node_(declare_int("node", 3, {.doc = "CANopen node id of the drive", .min = 1, .max = 127})),
      counts_per_unit_(declare_float("counts_per_unit", 10000.0,
                                     {.doc = "drive position units per metre or radian of the axis", .min = 1e-6})),
      max_velocity_(declare_float("max_velocity", 1.0, {.doc = "unit/s, also the default move speed", .min = 1e-6})),
      acceleration_(
          declare_float("acceleration", 2.0, {.doc = "unit/s^2, the drive's profile acceleration", .min = 1e-6})),
      position_min_(declare_float("position_min", -1.0, {.doc = "unit, lower soft limit (from home)"})),
      position_max_(declare_float("position_max", 1.0, {.doc = "unit, upper soft limit (from home)"})),
      home_position_(
          declare_float("home_position", 0.0, {.doc = "unit, the position HOME assigns to where the axis is"})),
      heartbeat_ms_(declare_float("heartbeat_ms", 100.0,
                                  {.doc = "drive heartbeat producer time", .min = 1, .max = 65535, .unit = "ms"})),
      heartbeat_timeout_ms_(declare_float("heartbeat_timeout_ms", 350.0,
                                          {.doc = "drive silent this long: ERROR", .min = 1.0, .unit = "ms"})),
      sdo_timeout_ms_(declare_float("sdo_timeout_ms", 100.0,
                                    {.doc = "wait for each SDO answer in on()", .min = 1.0, .unit = "ms"})) {}

double ServoDriveCan::to_unit(int32_t counts) const noexcept {
  return static_cast<double>(counts - home_offset_.load(std::memory_order_relaxed)) / counts_per_unit_.get_float() +
         home_position_.get_float();
}

HookResult ServoDriveCan::on() {
  can_.copy_string(spec_, sizeof spec_);
  node_id_ = static_cast<uint8_t>(node_.get_int());
  // A missing bus fails here every retry: the error text goes into a fixed buffer (no
  // allocation in the command task, failures included) and becomes the ERROR's reason.
  devices::CanError error;
  if (!port_.open(spec_, error)) {
    set_error_reason(error.text);
    return HookResult::kError;
  }
  // The port registered its descriptor(s) as RT devices when it opened: mode-switch
  // detection allows their I/O in this component's RT tasks.
  const can_filter filters[] = {{co::kSdoTx + node_id_, CAN_SFF_MASK},
                                {co::kTpdo1 + node_id_, CAN_SFF_MASK},
                                {co::kTpdo2 + node_id_, CAN_SFF_MASK},
                                {co::kHeartbeat + node_id_, CAN_SFF_MASK}};
  if (!port_.set_filters(filters, error)) {
    set_error_reason(error.text);
    port_.close();
    return HookResult::kError;
  }
  const auto timeout = static_cast<int64_t>(sdo_timeout_ms_.get_float() * 1e6);
  const double cpu = counts_per_unit_.get_float();
  const auto acc = static_cast<uint32_t>(std::lround(acceleration_.get_float() * cpu));
  const auto vel = static_cast<uint32_t>(std::lround(max_velocity_.get_float() * cpu));
  auto w = [&](uint16_t index, uint8_t sub, uint32_t value, uint8_t size) {
    return co::sdo_write_wait(port_, node_id_, index, sub, value, size, timeout) == co::SdoResult::kOk;
  };
  uint32_t position = 0;
  if (port_.send(co::nmt(co::kNmtPreOperational, node_id_)).status != IoStatus::kOk ||
      !w(co::kObjModesOfOperation, 0, static_cast<uint8_t>(co::kModeProfilePosition), 1) ||
      !w(co::kObjProfileAcceleration, 0, acc, 4) || !w(co::kObjProfileDeceleration, 0, acc, 4) ||
      !w(co::kObjProfileVelocity, 0, vel, 4) ||
      !w(co::kObjHeartbeatTime, 0, static_cast<uint32_t>(std::lround(heartbeat_ms_.get_float())), 2) ||
      !w(co::kObjTpdo1Comm, 2, 1, 1) || !w(co::kObjTpdo2Comm, 2, 1, 1) ||
      co::sdo_read_wait(port_, node_id_, co::kObjPositionActual, 0, position, timeout) != co::SdoResult::kOk ||
      !w(co::kObjTargetPosition, 0, position, 4) ||  // hold where it is
      !co::power_up(port_, node_id_, timeout) || port_.send(co::nmt(co::kNmtStart, node_id_)).status != IoStatus::kOk) {
    port_.close();
    return HookResult::kError;
  }
  position_ = static_cast<int32_t>(position);
  last_position_.store(position_, std::memory_order_relaxed);
  target_counts_ = position_;
  last_heartbeat_ns_ = rt::monotonic_ns();
  on_ns_ = last_heartbeat_ns_;
  nmt_left_operational_ = false;
  seen_operational_ = false;
  setpoint_high_ = moving_ = false;
  move_.clear();
  moves_.store(0, std::memory_order_relaxed);
  out_ = interfaces::ServoDriveData{};
  return HookResult::kOk;
}

void ServoDriveCan::off() {
  if (port_.is_open()) {
    (void)port_.send(co::rpdo1(node_id_, co::kCwQuickStop, target_counts_));
    (void)port_.send(co::rpdo1(node_id_, co::kCwShutdown, target_counts_));
  }
  port_.close();
}

HookResult ServoDriveCan::port_failed(const char* doing) noexcept {
  char reason[192];
  std::snprintf(reason, sizeof reason, "CAN port %s failed while %s", spec_, doing);
  set_error_reason(reason);
  return HookResult::kError;
}

HookResult ServoDriveCan::loop() {
  // Stale frames first (see ChassisCan::loop).
  auto handle = [this](const can_frame& f) {
    if ((f.can_id & CAN_ERR_FLAG) != 0) return;
    const canid_t id = f.can_id & CAN_SFF_MASK;
    if (id == co::kHeartbeat + node_id_ && f.len >= 1) {
      last_heartbeat_ns_ = rt::monotonic_ns();
      if (f.data[0] == co::kStateOperational) seen_operational_ = true;
      else if (seen_operational_) nmt_left_operational_ = true;
    } else if (id == co::kTpdo1 + node_id_ && f.len == 8) {
      velocity_ = static_cast<int32_t>(co::get_u32(&f.data[0]));
      position_ = static_cast<int32_t>(co::get_u32(&f.data[4]));
      got_tpdo1_ = true;
    } else if (id == co::kTpdo2 + node_id_ && f.len >= 2) {
      statusword_ = co::get_u16(&f.data[0]);
      got_tpdo2_ = true;
    }
  };
  for (int i = 0; i < 16; ++i) {
    can_frame f{};
    const devices::IoResult r = port_.receive(f, 0);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) return port_failed("receiving");
    handle(f);
  }
  // The set-point handshake: raise bit 4 with a new target; drop it once acknowledged.
  uint16_t cw = co::kCwEnableOperation;
  if (Move m; move_.take(m)) {
    target_counts_ = m.target;
    notify_ = m.requester;
    if (port_.send(co::rpdo2_profile_velocity(node_id_, m.velocity)).status == IoStatus::kClosed) {
      return port_failed("sending the profile velocity");
    }
    if (setpoint_high_) {
      // Still high from the previous move: drop it for one cycle so the next rises.
      (void)port_.send(co::rpdo1(node_id_, cw, target_counts_));
    }
    cw = static_cast<uint16_t>(cw | co::kCwNewSetPoint | 0x20);  // bit 5: change set immediately
    setpoint_high_ = true;
    moving_ = true;
  } else if (setpoint_high_) {
    if ((statusword_ & co::kSwSetPointAck) != 0) setpoint_high_ = false;
    else cw = static_cast<uint16_t>(cw | co::kCwNewSetPoint | 0x20);
  }
  got_tpdo1_ = got_tpdo2_ = false;
  if (port_.send(co::rpdo1(node_id_, cw, target_counts_)).status == IoStatus::kClosed ||
      port_.send(co::sync()).status == IoStatus::kClosed) {
    return port_failed("sending the set-point and SYNC");
  }
  const int64_t deadline = rt::monotonic_ns() + period_ns() / 2;
  while (!(got_tpdo1_ && got_tpdo2_)) {
    const int64_t wait = deadline - rt::monotonic_ns();
    if (wait <= 0) break;
    can_frame f{};
    const devices::IoResult r = port_.receive(f, wait);
    if (r.status == IoStatus::kTimeout) break;
    if (r.status != IoStatus::kOk) return port_failed("receiving the PDOs");
    handle(f);
  }
  const bool silent = rt::monotonic_ns() - last_heartbeat_ns_ >
                      static_cast<int64_t>(heartbeat_timeout_ms_.get_float() * 1e6);
  const bool faulted = got_tpdo2_ && ((statusword_ & co::kSwFault) != 0 ||
                                      (statusword_ & co::kSwStateMask) != co::kSwOperationEnabled);
  const int64_t timeout_ns = static_cast<int64_t>(heartbeat_timeout_ms_.get_float() * 1e6);
  const bool never_operational = !seen_operational_ && rt::monotonic_ns() - on_ns_ > timeout_ns;
  if (silent || faulted || nmt_left_operational_ || never_operational) {
    (void)port_.send(co::rpdo1(node_id_, co::kCwQuickStop, target_counts_));
    // The ERROR's reason (snprintf of integers into a fixed buffer: RT-safe).
    char reason[112];
    if (silent) {
      std::snprintf(reason, sizeof reason,
                    "drive node %u silent: no heartbeat for more than %.0f ms (heartbeat_timeout_ms)",
                    static_cast<unsigned>(node_id_), heartbeat_timeout_ms_.get_float());
    } else if (faulted) {
      std::snprintf(reason, sizeof reason, "drive node %u not operation-enabled: statusword 0x%04x",
                    static_cast<unsigned>(node_id_), static_cast<unsigned>(statusword_));
    } else if (nmt_left_operational_) {
      std::snprintf(reason, sizeof reason, "drive node %u left NMT operational (its heartbeat says so)",
                    static_cast<unsigned>(node_id_));
    } else {
      std::snprintf(reason, sizeof reason, "drive node %u: no heartbeat said NMT operational within %.0f ms of ON",
                    static_cast<unsigned>(node_id_), heartbeat_timeout_ms_.get_float());
    }
    set_error_reason(reason);
    return HookResult::kError;
  }
  last_position_.store(position_, std::memory_order_relaxed);
  const bool reached = (statusword_ & co::kSwTargetReached) != 0;
  // Reached only counts once the drive took this set-point (bit 4 dropped after the ack).
  if (moving_ && !setpoint_high_ && got_tpdo2_ && reached) {
    moving_ = false;
    ++out_.reached;
    if (notify_ != 0) {
      const double at = to_unit(position_);
      const tims::ConstBuffer part = tims::buffer_of(at);
      (void)data_endpoint().send(tims::Address(notify_), interfaces::kServoDrivePositionReached,
                                 std::span<const tims::ConstBuffer>(&part, 1));
    }
  }
  if (got_tpdo1_) {
    out_.position = to_unit(position_);
    out_.velocity = velocity_ / counts_per_unit_.get_float();
    out_.target = to_unit(target_counts_);
    out_.statusword = statusword_;
    out_.target_reached = reached && !moving_ ? 1 : 0;
    out_.homed = homed_.load(std::memory_order_relaxed) ? 1 : 0;
    out_.moves = moves_.load(std::memory_order_relaxed);
    publish(out_, rt::host_time_ns());
  }
  return HookResult::kOk;
}

bool ServoDriveCan::request_move(double target_unit, double velocity_unit, uint32_t requester) noexcept {
  const double cpu = counts_per_unit_.get_float();
  const double counts = (target_unit - home_position_.get_float()) * cpu + home_offset_.load(std::memory_order_relaxed);
  if (!std::isfinite(counts) || std::fabs(counts) > 2.0e9) return false;
  move_.post(Move{static_cast<int32_t>(std::lround(counts)),
                  static_cast<uint32_t>(std::lround(std::fabs(velocity_unit) * cpu)), requester});
  moves_.fetch_add(1, std::memory_order_relaxed);
  return true;
}

CommandResult ServoDriveCan::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  const bool enabled = state() == ComponentState::kEnabled;
  switch (request.type) {
    case interfaces::kServoDriveHome: {
      if (!body.empty()) {
        reject_malformed(request, "HOME takes no body");
        return CommandResult::kHandled;
      }
      if (!enabled) {
        reply_error(request, "HOME refused: the drive is not ENABLED");
        return CommandResult::kHandled;
      }
      home_offset_.store(last_position_.load(std::memory_order_relaxed), std::memory_order_relaxed);
      homed_.store(true, std::memory_order_relaxed);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    case interfaces::kServoDriveMovePos: {
      interfaces::ServoDriveMovePos m;
      if (body.size() != sizeof m) {
        reject_malformed(request, "MOVE_POS: body must be a ServoDriveMovePos (16 bytes)");
        return CommandResult::kHandled;
      }
      std::memcpy(&m, body.data(), sizeof m);
      if (!tims::body_is_native(request)) {
        tims::swap_fields(tims::fields_of<interfaces::ServoDriveMovePos>, reinterpret_cast<std::byte*>(&m), sizeof m);
      }
      const double vmax = max_velocity_.get_float();
      const double v = m.velocity == 0.0 ? vmax : std::fabs(m.velocity);
      if (!std::isfinite(m.position) || !std::isfinite(m.velocity)) {
        reject_malformed(request, "MOVE_POS: position and velocity must be finite");
      } else if (!enabled) {
        reply_error(request, "MOVE_POS refused: the drive is not ENABLED");
      } else if (!homed_.load(std::memory_order_relaxed)) {
        reply_error(request, "MOVE_POS refused: HOME first");
      } else if (m.position < position_min_.get_float() || m.position > position_max_.get_float()) {
        reply_error(request, "MOVE_POS refused: outside [position_min, position_max]");
      } else if (!request_move(m.position, v > vmax ? vmax : v, request.source().raw())) {
        reply_error(request, "MOVE_POS refused: position out of the drive's range");
      } else {
        reply(request, tims::msg::kOk);
      }
      return CommandResult::kHandled;
    }
    case interfaces::kServoDriveMoveVel: {
      interfaces::ServoDriveMoveVel m;
      if (body.size() != sizeof m) {
        reject_malformed(request, "MOVE_VEL: body must be a ServoDriveMoveVel (8 bytes)");
        return CommandResult::kHandled;
      }
      std::memcpy(&m, body.data(), sizeof m);
      if (!tims::body_is_native(request)) {
        tims::swap_fields(tims::fields_of<interfaces::ServoDriveMoveVel>, reinterpret_cast<std::byte*>(&m), sizeof m);
      }
      if (!std::isfinite(m.velocity)) {
        reject_malformed(request, "MOVE_VEL: velocity must be finite");
        return CommandResult::kHandled;
      }
      if (!enabled || !homed_.load(std::memory_order_relaxed)) {
        reply_error(request, !enabled ? "MOVE_VEL refused: the drive is not ENABLED" : "MOVE_VEL refused: HOME first");
        return CommandResult::kHandled;
      }
      // Profile position towards the limit in the direction of travel: the drive keeps
      // its own ramp and stops at the limit by itself. 0: stop where the axis is.
      const double vmax = max_velocity_.get_float();
      const double v = std::fabs(m.velocity) > vmax ? vmax : std::fabs(m.velocity);
      const double here = to_unit(last_position_.load(std::memory_order_relaxed));
      const double goal = m.velocity > 0   ? position_max_.get_float()
                          : m.velocity < 0 ? position_min_.get_float()
                                           : here;
      (void)request_move(goal, v == 0.0 ? vmax : v, 0);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    default: return CommandResult::kUnknown;
  }
}

}  // namespace rack::components
