#include "joystick.h"

#include "obstacle.h"

#include "rack/rt/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <algorithm>
#include <cmath>
#include <cstring>

namespace rack::components {

Joystick::Joystick()
    : DataComponent(DataTaskMode::kPeriodic),
      device_(declare_string("device", "/dev/input/js0",
                             {.doc = "joystick device (Linux joystick API)", .path = PathRole::kDevice})),
      chassis_(declare_string("chassis", "",
                              {.doc = "Chassis to drive as its active pilot (empty: only publish)",
                               .required = false,
                               .component_ref = true})),
      axis_forward_(declare_int("axis_forward", 1, {.doc = "axis for forward speed", .min = 0, .max = 7})),
      axis_turn_(declare_int("axis_turn", 0, {.doc = "axis for turning", .min = 0, .max = 7})),
      deadman_button_(declare_int("deadman_button", -1,
                                  {.doc = "button that must be held to move (-1: none)", .min = -1, .max = 31})),
      deadband_(
          declare_float("deadband", 0.05, {.doc = "axis values below this count as zero", .min = 0.0, .max = 0.9})),
      speed_scale_(declare_float("speed_scale", 0.5,
                                 {.doc = "fraction of the chassis vx_max at full stick", .min = 0.0, .max = 1.0})),
      // Its silence is judged by silence_ms (no forward motion), not an ERROR.
      obstacles_(declare_input<interfaces::Scan2dData, interfaces::LadarData>(
          "obstacles", {.doc = "Scan2D or Ladar whose scans limit the forward speed",
                        .optional = true,
                        .watched = false,
                        .silence_param = SilenceParam::kNone})),
      slow_distance_(declare_float("slow_distance", 1.0,
                                   {.doc = "m of free space ahead below which forward speed is reduced", .min = 0.01})),
      silence_ms_(declare_float(
          "silence_ms", 500.0,
          {.doc = "no scan from obstacles this long: no forward motion", .min = 1.0, .max = 3.6e6, .unit = "ms"})) {
  parameters().add_old_name("obstacle_timeout_ms", "silence_ms");  // docs/parameters.md
}

Joystick::~Joystick() { close_device(); }

void Joystick::close_device() noexcept {
  const rt::modeswitch::DeviceSetupScope setup;  // closing a device: deliberate set-up
  if (fd_ >= 0) {
    rt::modeswitch::unregister_rt_device(fd_);
    ::close(fd_);
  }
  fd_ = -1;
}

HookResult Joystick::on() {
  device_.copy_string(path_, sizeof path_);
  close_device();
  // A joystick is a character device (/dev/input/jsN); a FIFO is accepted too (rack-devsim
  // joystick --fifo plays one). A regular file or directory named by mistake is refused.
  // O_NONBLOCK: loop() reads what is there each cycle and never waits in read().
  mode_t kind = 0;
  {
    const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
    struct stat st {};
    if (::stat(path_, &st) == 0 && !S_ISCHR(st.st_mode) && !S_ISFIFO(st.st_mode)) {
      kind = st.st_mode;
    } else {
      fd_ = ::open(path_, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    }
  }
  if (kind != 0) {
    log_error("the joystick %s is %s, not a character device; retrying", static_cast<const char*>(path_),
              rt::file_kind_text(kind));
    return HookResult::kError;
  }
  if (fd_ < 0) {
    log_error("cannot open the joystick %s (errno %d); retrying", static_cast<const char*>(path_), errno);
    return HookResult::kError;
  }
  (void)rt::modeswitch::register_rt_device(fd_);  // loop() reads it every cycle
  state_ = interfaces::JoystickData{};
  events_.reset();
  chassis_address_ = resolved(chassis_);
  if (chassis_address_.raw() != 0) {
    if (switch_on(chassis_address_) != HookResult::kOk) return HookResult::kError;  // cascading ON
    const interfaces::ChassisSetActivePilot p{address().raw()};
    const int64_t timeout = settings().rpc_timeout_ns;
    if (!command_endpoint().call(chassis_address_, interfaces::kChassisSetActivePilot, p, reply_, timeout).ok()) {
      return HookResult::kError;
    }
    const tims::CallResult r = command_endpoint().call(chassis_address_, interfaces::kChassisGetParams, reply_,
                                                       timeout);
    if (r.status != tims::CallStatus::kOk || r.reply.type != interfaces::kChassisParamsReply ||
        r.body.size() != sizeof limits_) {
      return HookResult::kError;
    }
    std::memcpy(&limits_, r.body.data(), sizeof limits_);
    if (!tims::body_is_native(r.reply)) {
      tims::swap_fields(tims::fields_of<interfaces::ChassisParams>, reinterpret_cast<std::byte*>(&limits_),
                        sizeof limits_);
    }
  }
  free_ahead_ = 0.0;  // the obstacles' source is on and subscribed already (declared input)
  return HookResult::kOk;
}

bool Joystick::take_obstacles() noexcept {
  const double front = limits_.boundary_front + limits_.safety_margin;
  const double half = std::fmax(limits_.boundary_left, limits_.boundary_right) + limits_.safety_margin;
  const Received r = receive([&](const InputPort&) {
    if (chassis_address_.raw() == 0) return;  // no outline to look ahead of
    free_ahead_ = obstacles_.holds<interfaces::Scan2dData>()
                      ? obstacle::free_ahead(obstacles_.value<interfaces::Scan2dData>(), front, half)
                      : obstacle::free_ahead(obstacles_.value<interfaces::LadarData>(), front, half);
  });
  return !r.failed;  // failed: the source left ENABLED
}

void Joystick::off() {
  if (chassis_address_.raw() != 0) {
    // Stop and release: bounded calls; the chassis may already be gone.
    const interfaces::ChassisMove stop{};
    const int64_t timeout = settings().rpc_timeout_ns;
    (void)command_endpoint().call(chassis_address_, interfaces::kChassisMove, stop, reply_, timeout);
    const interfaces::ChassisSetActivePilot none{};
    (void)command_endpoint().call(chassis_address_, interfaces::kChassisSetActivePilot, none, reply_, timeout);
  }
  close_device();
}

HookResult Joystick::loop() {
  for (int i = 0; i < 8; ++i) {
    const ssize_t n = ::read(fd_, events_.space(), events_.space_size());
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) break;
    if (n <= 0) {  // unplugged (ENODEV) or the FIFO's writer left
      log_error("%s: the joystick is gone; the robot stops, reopening", static_cast<const char*>(path_));
      return HookResult::kError;
    }
    events_.received(static_cast<std::size_t>(n), state_);
  }
  state_.vx = state_.omega = 0.0;
  state_.free_ahead = -1.0;
  if (obstacles_.configured()) {
    if (!take_obstacles()) return HookResult::kError;  // off() stops the robot; the retry re-subscribes
    const bool stale = static_cast<double>(rt::monotonic_ns() - obstacles_.received_ns()) >
                       silence_ms_.get_float() * 1e6;
    state_.free_ahead = stale ? 0.0 : std::fmin(free_ahead_, 1e3);
  }
  if (chassis_address_.raw() != 0) {
    auto shaped = [this](uint32_t axis) {
      const double v = -static_cast<double>(state_.axis[axis]);
      return std::fabs(v) < deadband_.get_float() ? 0.0 : v;
    };
    const int64_t deadman = deadman_button_.get_int();
    const bool armed = deadman < 0 || (state_.buttons & (1U << deadman)) != 0;
    if (armed) {
      state_.vx = shaped(static_cast<uint32_t>(axis_forward_.get_int())) * limits_.vx_max * speed_scale_.get_float();
      state_.omega = shaped(static_cast<uint32_t>(axis_turn_.get_int())) * limits_.omega_max;
      if (state_.vx > 0.0 && state_.free_ahead >= 0.0) {  // slow down before what is ahead
        state_.vx *= std::clamp(state_.free_ahead / slow_distance_.get_float(), 0.0, 1.0);
      }
    }
    const interfaces::ChassisMove m{state_.vx, 0.0, state_.omega};
    // Bounded by half a period; a refused or lost MOVE is counted and the chassis
    // watchdog stops the robot if they keep failing.
    const tims::CallResult r = data_endpoint().call(chassis_address_, interfaces::kChassisMove, m, reply_,
                                                    period_ns() / 2);
    if (!r.ok()) ++state_.moves_rejected;
  }
  publish(state_, rt::host_time_ns());
  return HookResult::kOk;
}

}  // namespace rack::components
