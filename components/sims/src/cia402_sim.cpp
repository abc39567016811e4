#include "rack/sims/cia402_sim.h"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <system_error>

#include "rack/devices/canopen.h"
#include "rack/rt/clock.h"

namespace rack::sims {

namespace co = devices::canopen;

Cia402DriveSim::Cia402DriveSim(Config config) : config_(std::move(config)) {
  for (const uint8_t id : config_.nodes) {
    Drive d;
    d.id = id;
    d.s.nmt = co::kStatePreOperational;
    d.s.statusword = co::kSwSwitchOnDisabled;
    drives_.push_back(d);
  }
}

Cia402DriveSim::~Cia402DriveSim() { stop(); }

void Cia402DriveSim::attach(int fd) {
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
  fd_ = fd;
}

void Cia402DriveSim::listen_unix(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof addr.sun_path) throw std::runtime_error(path + ": socket path too long");
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  ::unlink(path.c_str());
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 || ::listen(fd, 4) != 0) {
    const int e = errno;
    if (fd >= 0) ::close(fd);
    throw std::system_error(e, std::generic_category(), "Cia402DriveSim: listen on " + path);
  }
  listen_fd_ = fd;
  listen_path_ = path;
}

void Cia402DriveSim::start() {
  stop_ = false;
  thread_ = std::thread([this] { run(); });
}

void Cia402DriveSim::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (fd_ >= 0) ::close(fd_);
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    ::unlink(listen_path_.c_str());
  }
  fd_ = listen_fd_ = -1;
}

void Cia402DriveSim::set_silent(uint8_t node, bool silent) {
  std::lock_guard lock(mutex_);
  if (Drive* d = find(node)) d->silent = silent;
}

void Cia402DriveSim::hold_nmt(uint8_t node, uint8_t state) {
  std::lock_guard lock(mutex_);
  if (Drive* d = find(node)) {
    d->nmt_held = true;
    d->s.nmt = state;
  }
}

void Cia402DriveSim::release_nmt(uint8_t node) {
  std::lock_guard lock(mutex_);
  if (Drive* d = find(node)) d->nmt_held = false;
}

void Cia402DriveSim::drop_client() { drop_ = true; }

bool Cia402DriveSim::has_client() const {
  std::lock_guard lock(mutex_);
  return fd_ >= 0;
}

Cia402DriveSim::DriveState Cia402DriveSim::state(uint8_t node) const {
  std::lock_guard lock(mutex_);
  for (const Drive& d : drives_) {
    if (d.id == node) return d.s;
  }
  return {};
}

Cia402DriveSim::Drive* Cia402DriveSim::find(uint8_t id) {
  for (Drive& d : drives_) {
    if (d.id == id) return &d;
  }
  return nullptr;
}

void Cia402DriveSim::send(uint32_t id, const uint8_t* data, uint8_t len) {
  if (fd_ < 0) return;
  if (silenced_by_bus_off_ && (id & CAN_ERR_FLAG) == 0) return;
  can_frame f{};
  f.can_id = id;
  f.len = len;
  std::memcpy(f.data, data, len);
  (void)::send(fd_, &f, sizeof f, MSG_DONTWAIT | MSG_NOSIGNAL);
}

void Cia402DriveSim::send_garbage() {
  const uint8_t junk[5] = {0xde, 0xad, 0xbe, 0xef, 0x00};
  (void)::send(fd_, junk, sizeof junk, MSG_DONTWAIT | MSG_NOSIGNAL);  // not a can_frame
  can_frame f{};
  f.can_id = 0x123;
  f.len = 15;  // dlc beyond 8: a classic frame cannot carry it
  (void)::send(fd_, &f, sizeof f, MSG_DONTWAIT | MSG_NOSIGNAL);
  const uint8_t data[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  send(0x7E5, data, 8);  // a valid frame from nobody the drivers know
  // A TPDO from a node that is not configured (node 99).
  send(co::kTpdo1 + 99, data, 8);
}

void Cia402DriveSim::control(Drive& d, uint16_t cw) {
  uint16_t& sw = d.s.statusword;
  // The power state lives in the bits of kSwStateMask; target reached (10) and set-point
  // acknowledge (12) are kept across controlwords.
  auto set_state = [&sw](uint16_t state) {
    sw = static_cast<uint16_t>((sw & ~(co::kSwStateMask | co::kSwFault)) | state);
  };
  const uint16_t state = sw & co::kSwStateMask;
  if ((sw & co::kSwFault) != 0) {
    if ((cw & co::kCwFaultReset) != 0) set_state(co::kSwSwitchOnDisabled);
    return;
  }
  if ((cw & 0x82) == 0x00) {  // disable voltage
    set_state(co::kSwSwitchOnDisabled);
    d.position_active = false;
  } else if ((cw & 0x86) == 0x02) {  // quick stop
    set_state(co::kSwSwitchOnDisabled);
    d.position_active = false;
    d.s.velocity = 0.0;
    d.s.target_velocity = 0;
  } else if ((cw & 0x87) == 0x06) {  // shutdown
    set_state(co::kSwReadyToSwitchOn);
  } else if ((cw & 0x8F) == 0x07) {  // switch on / disable operation
    if (state == co::kSwReadyToSwitchOn || state == co::kSwOperationEnabled) set_state(co::kSwSwitchedOn);
  } else if ((cw & 0x8F) == 0x0F) {  // enable operation
    if (state == co::kSwSwitchedOn || state == co::kSwOperationEnabled) set_state(co::kSwOperationEnabled);
  }
  // Profile position: a rising "new set-point" bit latches the target and is
  // acknowledged (bit 12) until the master drops bit 4.
  const bool setpoint = (cw & co::kCwNewSetPoint) != 0;
  if (setpoint && !d.new_setpoint && (sw & co::kSwStateMask) == co::kSwOperationEnabled) {
    sw = static_cast<uint16_t>((sw | co::kSwSetPointAck) & ~co::kSwTargetReached);
    d.position_active = true;  // the drive moves until the set-point is reached
    d.s.active_target = d.s.target_position;
  } else if (!setpoint) {
    sw = static_cast<uint16_t>(sw & ~co::kSwSetPointAck);
  }
  d.new_setpoint = setpoint;
}

void Cia402DriveSim::handle_sdo(Drive& d, const uint8_t* data) {
  const uint8_t cmd = data[0];
  const uint16_t index = co::get_u16(&data[1]);
  const uint8_t sub = data[3];
  const uint32_t value = co::get_u32(&data[4]);
  ++d.s.sdos;
  uint8_t out[8] = {0, data[1], data[2], sub, 0, 0, 0, 0};
  auto abort = [&](uint32_t code) {
    out[0] = 0x80;
    co::put_u32(&out[4], code);
    send(co::kSdoTx + d.id, out, 8);
  };
  if ((cmd & 0xE0) == 0x20) {  // download (write)
    switch (index) {
      case co::kObjHeartbeatTime:
        d.s.heartbeat_ms = static_cast<uint16_t>(value);
        d.next_heartbeat_ns = 0;
        break;
      case co::kObjTpdo1Comm:
      case co::kObjTpdo2Comm:
        if (sub != 2) return abort(co::kAbortNoObject);
        d.tpdo_type[index - co::kObjTpdo1Comm] = static_cast<uint8_t>(value);
        break;
      case co::kObjControlword: control(d, static_cast<uint16_t>(value)); break;
      case co::kObjModesOfOperation:
        if (static_cast<int8_t>(value) != co::kModeProfileVelocity &&
            static_cast<int8_t>(value) != co::kModeProfilePosition) {
          return abort(co::kAbortUnsupported);
        }
        d.s.mode = static_cast<int8_t>(value);
        break;
      case co::kObjTargetPosition: d.s.target_position = static_cast<int32_t>(value); break;
      case co::kObjProfileVelocity: d.profile_velocity = value; break;
      case co::kObjProfileAcceleration: d.acceleration = value; break;
      case co::kObjProfileDeceleration: d.deceleration = value; break;
      case co::kObjTargetVelocity: d.s.target_velocity = static_cast<int32_t>(value); break;
      default: return abort(co::kAbortNoObject);
    }
    out[0] = 0x60;
    send(co::kSdoTx + d.id, out, 8);
    return;
  }
  if (cmd == 0x40) {  // upload (read), expedited answers only
    uint32_t v = 0;
    uint8_t size = 4;
    switch (index) {
      case co::kObjHeartbeatTime:
        v = d.s.heartbeat_ms;
        size = 2;
        break;
      case co::kObjStatusword:
        v = d.s.statusword;
        size = 2;
        break;
      case co::kObjModesOfOperation:
        v = static_cast<uint8_t>(d.s.mode);
        size = 1;
        break;
      case co::kObjPositionActual: v = static_cast<uint32_t>(static_cast<int32_t>(std::lround(d.s.position))); break;
      case co::kObjVelocityActual: v = static_cast<uint32_t>(static_cast<int32_t>(std::lround(d.s.velocity))); break;
      default: return abort(co::kAbortNoObject);
    }
    out[0] = static_cast<uint8_t>(0x43 | ((4 - size) << 2));
    co::put_u32(&out[4], v);
    send(co::kSdoTx + d.id, out, 8);
    return;
  }
  abort(co::kAbortUnsupported);
}

void Cia402DriveSim::handle(const uint8_t* data, std::size_t len) {
  if (len != sizeof(can_frame)) return;  // a real bus never carries this; ignore like a drive would
  can_frame f;
  std::memcpy(&f, data, sizeof f);
  if (f.len > 8 || (f.can_id & (CAN_ERR_FLAG | CAN_RTR_FLAG)) != 0) return;
  const canid_t id = f.can_id & CAN_SFF_MASK;
  if (id == co::kNmt && f.len == 2) {
    for (Drive& d : drives_) {
      if (f.data[1] != 0 && f.data[1] != d.id) continue;
      if (d.silent || d.nmt_held) continue;
      switch (f.data[0]) {
        case co::kNmtStart: d.s.nmt = co::kStateOperational; break;
        case co::kNmtStop: d.s.nmt = co::kStateStopped; break;
        case co::kNmtPreOperational: d.s.nmt = co::kStatePreOperational; break;
        case co::kNmtResetNode: {
          const Drive fresh = [&] {
            Drive n;
            n.id = d.id;
            n.s.statusword = co::kSwSwitchOnDisabled;
            n.s.position = d.s.position;  // the encoder keeps counting across a reset
            return n;
          }();
          d = fresh;
          const uint8_t boot = co::kStateBootUp;
          send(co::kHeartbeat + d.id, &boot, 1);
          d.s.nmt = co::kStatePreOperational;
          break;
        }
        default: break;
      }
    }
    return;
  }
  if (id == co::kSync) {
    for (Drive& d : drives_) {
      if (d.silent || d.s.nmt != co::kStateOperational) continue;
      ++d.s.syncs;
      uint8_t t1[8];
      co::put_u32(&t1[0], static_cast<uint32_t>(static_cast<int32_t>(std::lround(d.s.velocity))));
      co::put_u32(&t1[4], static_cast<uint32_t>(static_cast<int32_t>(std::lround(d.s.position))));
      send(co::kTpdo1 + d.id, t1, 8);
      uint8_t t2[2];
      co::put_u16(t2, d.s.statusword);
      send(co::kTpdo2 + d.id, t2, 2);
    }
    return;
  }
  const uint8_t node = static_cast<uint8_t>(id & 0x7F);
  Drive* d = find(node);
  if (d == nullptr || d->silent) return;
  const canid_t fn = id & 0x780;
  if (fn == co::kSdoRx && f.len == 8 && d->s.nmt != co::kStateStopped) {
    handle_sdo(*d, f.data);
  } else if (fn == co::kRpdo1 && f.len == 6 && d->s.nmt == co::kStateOperational) {
    ++d->s.rpdos;
    const int32_t target = static_cast<int32_t>(co::get_u32(&f.data[2]));
    if (d->s.mode == co::kModeProfilePosition) d->s.target_position = target;
    else d->s.target_velocity = target;
    control(*d, co::get_u16(&f.data[0]));
  } else if (fn == co::kRpdo2 && f.len >= 4 && d->s.nmt == co::kStateOperational) {
    ++d->s.rpdos;
    d->profile_velocity = co::get_u32(&f.data[0]);
  }
}

void Cia402DriveSim::tick(double dt, int64_t now) {
  for (Drive& d : drives_) {
    const bool enabled = (d.s.statusword & co::kSwStateMask) == co::kSwOperationEnabled;
    double target = 0.0;
    if (enabled && d.s.mode == co::kModeProfileVelocity) {
      target = d.s.target_velocity;
    } else if (enabled && d.s.mode == co::kModeProfilePosition && d.position_active) {
      const double err = d.s.active_target - d.s.position;
      const double v = std::min<double>(d.profile_velocity, std::fabs(err) / dt);
      target = err >= 0 ? v : -v;
    }
    if (!enabled) {
      d.s.velocity = 0.0;  // power stage off
    } else {
      const double rate = (std::fabs(target) < std::fabs(d.s.velocity) ? d.deceleration : d.acceleration) * dt;
      d.s.velocity += std::clamp(target - d.s.velocity, -rate, rate);
      if (d.s.mode == co::kModeProfilePosition) d.s.velocity = target;  // position mode: no ramp modelled
    }
    d.s.position += d.s.velocity * dt;
    const bool reached = d.s.mode == co::kModeProfilePosition
                             ? d.position_active && std::fabs(d.s.active_target - d.s.position) < 1.0
                             : std::fabs(target - d.s.velocity) < 1.0;
    d.s.statusword = static_cast<uint16_t>(reached ? d.s.statusword | co::kSwTargetReached
                                                   : d.s.statusword & ~co::kSwTargetReached);
    if (d.s.heartbeat_ms > 0 && !d.silent && now >= d.next_heartbeat_ns) {
      send(co::kHeartbeat + d.id, &d.s.nmt, 1);
      d.next_heartbeat_ns = now + d.s.heartbeat_ms * rt::kNsPerMs;
    }
  }
}

void Cia402DriveSim::receive(const uint8_t* data, std::size_t len) {
  std::lock_guard lock(mutex_);
  handle(data, len);
}

void Cia402DriveSim::advance(double dt_s, int64_t now_ns) {
  std::lock_guard lock(mutex_);
  tick(dt_s, now_ns);
}

void Cia402DriveSim::run() {
  int64_t last = rt::monotonic_ns();
  int64_t next = last + config_.tick_ns;
  uint8_t buf[64];
  while (!stop_) {
    if (drop_.exchange(false) && fd_ >= 0) {
      std::lock_guard lock(mutex_);
      ::close(fd_);
      fd_ = -1;
    }
    if (fd_ < 0 && listen_fd_ >= 0) {
      const int c = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (c >= 0) {
        std::lock_guard lock(mutex_);
        fd_ = c;
      }
    }
    pollfd p{fd_ >= 0 ? fd_ : listen_fd_, POLLIN, 0};
    int64_t left = next - rt::monotonic_ns();
    if (left < 0) left = 0;
    const timespec ts = rt::to_timespec(left);
    if (p.fd >= 0) {
      (void)::ppoll(&p, 1, &ts, nullptr);
    } else {
      rt::sleep_for(left);
    }
    std::lock_guard lock(mutex_);
    while (fd_ >= 0) {
      const ssize_t n = ::recv(fd_, buf, sizeof buf, MSG_DONTWAIT);
      if (n > 0) {
        handle(buf, static_cast<std::size_t>(n));
        continue;
      }
      if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
        // The master went away. Real drives notice through their own heartbeat
        // consumer or node guarding and stop; do the same.
        ::close(fd_);
        fd_ = -1;
        for (Drive& d : drives_) {
          d.s.target_velocity = 0;
          d.s.statusword = co::kSwSwitchOnDisabled;
        }
      }
      break;
    }
    const int64_t now = rt::monotonic_ns();
    if (now >= next) {
      tick(static_cast<double>(now - last) * 1e-9, now);
      last = now;
      next += config_.tick_ns;
      if (next < now) next = now + config_.tick_ns;
      for (int g = garbage_.exchange(0); g > 0 && fd_ >= 0; --g) send_garbage();
      const int64_t restart = bus_off_.exchange(-1);
      if (restart >= 0 && fd_ >= 0) {
        const uint8_t none[8] = {};
        send(CAN_ERR_FLAG | CAN_ERR_BUSOFF, none, 8);
        restart_at_ns_ = now + restart;
        silenced_by_bus_off_ = true;  // a controller off the bus sends nothing
      }
      if (restart_at_ns_ >= 0 && now >= restart_at_ns_) {
        restart_at_ns_ = -1;
        silenced_by_bus_off_ = false;
        const uint8_t none[8] = {};
        send(CAN_ERR_FLAG | CAN_ERR_RESTARTED, none, 8);
      }
    }
  }
}

}  // namespace rack::sims
