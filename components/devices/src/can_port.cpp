#include "rack/devices/can_port.h"
#include "rack/rt/input_file.h"
#include "rack/rt/modeswitch.h"

#include <fcntl.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "poll_util.h"
#include "rack/rt/clock.h"

namespace rack::devices {

namespace {
// "name: what: errno text" into `error`. No allocation: strerrordesc_np (glibc 2.32)
// returns a constant, where strerror may format an unknown errno into a new buffer.
void errno_text(CanError& error, const char* what, const char* name, int err = errno) noexcept {
  const char* desc = strerrordesc_np(err);
  std::snprintf(error.text, sizeof error.text, "%s: %s: %s", name, what, desc != nullptr ? desc : "unknown error");
}
}  // namespace

CanPort::~CanPort() { close(); }

bool CanPort::configure_common(CanError& error) noexcept {
  const int on = 1;
  // Software receive timestamps in the host clock, on CAN and AF_UNIX sockets alike.
  if (::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) {
    errno_text(error, "SO_TIMESTAMPNS", "CAN socket");
    return false;
  }
  const int flags = ::fcntl(fd_, F_GETFL);
  if (flags < 0 || ::fcntl(fd_, F_SETFL, flags | O_NONBLOCK) != 0) {
    errno_text(error, "O_NONBLOCK", "CAN socket");
    return false;
  }
  return true;
}

bool CanPort::open_socketcan(const char* ifname, CanError& error) noexcept {
  const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
  close();
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    errno_text(error, "socket(PF_CAN) (does this kernel have CAN support? modprobe can-raw)", ifname);
    return false;
  }
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, ifname, IFNAMSIZ - 1);
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) {
    errno_text(error, "no such CAN interface", ifname);
    ::close(fd);
    return false;
  }
  // Every controller error class: bus-off, error passive, restarts, lost arbitration.
  const can_err_mask_t mask = CAN_ERR_MASK;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) != 0) {
    errno_text(error, "CAN_RAW_ERR_FILTER", ifname);
    ::close(fd);
    return false;
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    errno_text(error, "bind", ifname);
    ::close(fd);
    return false;
  }
  return take(fd, CanKind::kSocketCan, error, /*close_on_failure=*/true);
}

bool CanPort::open_unix(const char* path, CanError& error) noexcept {
  const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
  close();
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (std::strlen(path) >= sizeof addr.sun_path) {
    std::snprintf(error.text, sizeof error.text, "%s: socket path too long", path);
    return false;
  }
  std::strncpy(addr.sun_path, path, sizeof addr.sun_path - 1);
  // A simulated bus is a Unix socket; anything else there is named for what it is
  // (connect() would only say "Connection refused"). When stat() fails, connect() says why.
  struct stat st {};
  if (::stat(path, &st) == 0 && !S_ISSOCK(st.st_mode)) {
    std::snprintf(error.text, sizeof error.text, "%s: the CAN bus socket is %s, not a socket", path,
                  rt::file_kind_text(st.st_mode));
    return false;
  }
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    errno_text(error, "socket(AF_UNIX, SOCK_SEQPACKET)", path);
    return false;
  }
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    errno_text(error, "connect", path);
    ::close(fd);
    return false;
  }
  return take(fd, CanKind::kOther, error, /*close_on_failure=*/true);
}

bool CanPort::open(const char* spec, CanError& error) noexcept {
  if (std::strncmp(spec, "unix:", 5) == 0) return open_unix(spec + 5, error);
  return open_socketcan(spec, error);
}

// The std::string forms (set-up code, tests): the same, with the text copied.
bool CanPort::open_socketcan(const char* ifname, std::string& error) {
  CanError e;
  if (open_socketcan(ifname, e)) return true;
  error = e.text;
  return false;
}

bool CanPort::open_unix(const char* path, std::string& error) {
  CanError e;
  if (open_unix(path, e)) return true;
  error = e.text;
  return false;
}

bool CanPort::open(const char* spec, std::string& error) {
  CanError e;
  if (open(spec, e)) return true;
  error = e.text;
  return false;
}

void CanPort::adopt(int fd) {
  const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
  close();
  CanError ignored;
  (void)take(fd, CanKind::kOther, ignored, /*close_on_failure=*/false);  // best effort: a socketpair supports both
}

bool CanPort::take(int fd, CanKind kind, CanError& error, bool close_on_failure) noexcept {
  fd_ = fd;
  kind_ = kind;
  (void)rt::modeswitch::register_rt_device(fd_);  // RT tasks send, receive and poll on it
  if (configure_common(error)) return true;
  if (close_on_failure) close();
  return false;
}

void CanPort::close() noexcept {
  const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
  if (fd_ >= 0) {
    rt::modeswitch::unregister_rt_device(fd_);
    ::close(fd_);
  }
  fd_ = -1;
  kind_ = CanKind::kNone;
  bus_off_.store(false, std::memory_order_relaxed);
  error_passive_ = false;
}

bool CanPort::set_filters(std::span<const can_filter> filters, CanError& error) noexcept {
  if (filters.size() > kMaxFilters) {
    std::snprintf(error.text, sizeof error.text, "CAN: at most %zu filters", kMaxFilters);
    return false;
  }
  std::copy(filters.begin(), filters.end(), filters_.begin());
  filter_count_ = filters.size();
  if (kind_ == CanKind::kSocketCan) {
    const rt::modeswitch::DeviceSetupScope setup;  // setsockopt: deliberate set-up in on()
    // No filters on a raw socket means "receive all"; an empty list must mean the same.
    if (!filters.empty() && ::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                                         static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0) {
      errno_text(error, "CAN_RAW_FILTER", "CAN socket");
      return false;
    }
  }
  return true;
}

bool CanPort::set_filters(std::span<const can_filter> filters, std::string& error) {
  CanError e;
  if (set_filters(filters, e)) return true;
  error = e.text;
  return false;
}

bool CanPort::accepted(canid_t id) const noexcept {
  if (filter_count_ == 0 || kind_ == CanKind::kSocketCan) return true;  // the kernel filtered
  for (std::size_t i = 0; i < filter_count_; ++i) {
    const can_filter& f = filters_[i];
    const bool match = ((id ^ f.can_id) & f.can_mask & ~CAN_INV_FILTER) == 0;
    if (((f.can_id & CAN_INV_FILTER) != 0) != match) return true;
  }
  return false;
}

void CanPort::handle_error_frame(const can_frame& f) noexcept {
  ++counters_.error_frames;
  if ((f.can_id & CAN_ERR_BUSOFF) != 0) {
    if (!bus_off_.load(std::memory_order_relaxed)) ++counters_.bus_off;
    bus_off_.store(true, std::memory_order_relaxed);
  }
  if ((f.can_id & CAN_ERR_RESTARTED) != 0) bus_off_.store(false, std::memory_order_relaxed);
  if ((f.can_id & CAN_ERR_CRTL) != 0 && f.len >= 2) {
    const uint8_t c = f.data[1];
    if ((c & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0) error_passive_ = true;
    if ((c & CAN_ERR_CRTL_ACTIVE) != 0) error_passive_ = false;
  }
}

IoResult CanPort::receive(can_frame& frame, int64_t timeout_ns) noexcept {
  IoResult r;
  if (fd_ < 0) {
    r.status = IoStatus::kClosed;
    r.error = EBADF;
    return r;
  }
  const int64_t deadline = rt::monotonic_ns() + timeout_ns;
  // A caller that gives a timeout usually expects to wait (an answer to what it just
  // sent): ppoll first, then one recvmsg (two system calls instead of a failing
  // recvmsg, ppoll and recvmsg). With timeout 0 (draining), recvmsg alone.
  bool poll_first = timeout_ns > 0;
  for (;;) {
    if (poll_first) {
      poll_first = false;
      short revents = 0;
      const int w = detail::wait_fd(fd_, POLLIN, deadline - rt::monotonic_ns(), revents);
      if (w == 0) {
        r.status = IoStatus::kTimeout;
        return r;
      }
      if (w < 0) {
        r.error = -w;
        return r;
      }
    }
    iovec iov{&frame, sizeof frame};
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control_;
    msg.msg_controllen = sizeof control_;
    const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      short revents = 0;
      const int64_t left = deadline - rt::monotonic_ns();
      if (left <= 0) {
        r.status = IoStatus::kTimeout;
        return r;
      }
      const int w = detail::wait_fd(fd_, POLLIN, left, revents);
      if (w == 0) {
        r.status = IoStatus::kTimeout;
        return r;
      }
      if (w < 0) {
        r.error = -w;
        return r;
      }
      continue;  // readable (or hung up: recvmsg says which)
    }
    if (n == 0) {  // seqpacket peer closed (a CAN_RAW socket never reads 0)
      r.status = IoStatus::kClosed;
      return r;
    }
    if (n < 0) {
      r.status = (errno == ENETDOWN || errno == ENODEV || errno == ECONNRESET) ? IoStatus::kClosed : IoStatus::kError;
      r.error = errno;
      return r;
    }
    if (static_cast<std::size_t>(n) != sizeof frame || (msg.msg_flags & MSG_TRUNC) != 0 || frame.len > CAN_MAX_DLEN) {
      ++counters_.malformed;  // a CAN FD frame, a short packet or a broken peer
      continue;
    }
    r.stamp_ns = 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec ts;
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        r.stamp_ns = rt::from_timespec(ts);
      }
    }
    if (r.stamp_ns == 0) r.stamp_ns = rt::host_time_ns();
    if ((frame.can_id & CAN_ERR_FLAG) != 0) {
      handle_error_frame(frame);
    } else {
      if (!accepted(frame.can_id)) {
        ++counters_.filtered;
        continue;
      }
      ++counters_.received;
      // A controller that delivers frames is on the bus again (restart-ms did it).
      bus_off_.store(false, std::memory_order_relaxed);
    }
    r.status = IoStatus::kOk;
    r.bytes = sizeof frame;
    return r;
  }
}

IoResult CanPort::send(const can_frame& frame) noexcept {
  IoResult r;
  if (fd_ < 0) {
    r.status = IoStatus::kClosed;
    r.error = EBADF;
    return r;
  }
  if (bus_off_.load(std::memory_order_relaxed)) {
    ++counters_.send_failed;
    r.error = ENETDOWN;
    return r;
  }
  const ssize_t n = ::send(fd_, &frame, sizeof frame, MSG_DONTWAIT | MSG_NOSIGNAL);
  if (n == static_cast<ssize_t>(sizeof frame)) {
    ++counters_.sent;
    r.status = IoStatus::kOk;
    r.bytes = sizeof frame;
    return r;
  }
  ++counters_.send_failed;
  r.error = n < 0 ? errno : EMSGSIZE;
  r.status = (r.error == EPIPE || r.error == ECONNRESET || r.error == ENOTCONN || r.error == ENODEV) ? IoStatus::kClosed
                                                                                                     : IoStatus::kError;
  return r;
}

can_frame make_frame(canid_t id, std::span<const uint8_t> data) noexcept {
  can_frame f{};
  f.can_id = id;
  f.len = static_cast<uint8_t>(data.size() > CAN_MAX_DLEN ? CAN_MAX_DLEN : data.size());
  std::memcpy(f.data, data.data(), f.len);
  return f;
}

}  // namespace rack::devices
