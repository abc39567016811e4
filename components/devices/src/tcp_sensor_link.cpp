#include "rack/devices/tcp_sensor_link.h"
#include "rack/rt/modeswitch.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "poll_util.h"
#include "rack/rt/clock.h"

namespace rack::devices {

TcpSensorLink::~TcpSensorLink() { close(); }

void TcpSensorLink::open(TcpSensorConfig config) {
  close();
  config_ = std::move(config);
  capacity_ = std::max<std::size_t>(config_.ring_bytes, 4096);
  ring_ = std::make_unique<uint8_t[]>(capacity_);
  receive_ = std::make_unique<uint8_t[]>(kReceiveBytes);
  head_.store(0);
  tail_.store(0);
  epoch_.store(0);
  seen_epoch_ = 0;
  data_event_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  control_event_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (data_event_ < 0 || control_event_ < 0) {
    const int e = errno;
    close();
    throw std::system_error(e, std::generic_category(), "TcpSensorLink: eventfd");
  }
  // The RT side polls and reads data_event_ and wakes the I/O thread through
  // control_event_: both are RT devices for the mode-switch detector.
  (void)rt::modeswitch::register_rt_device(data_event_);
  (void)rt::modeswitch::register_rt_device(control_event_);
  stop_.store(false);
}

void TcpSensorLink::request_stop() noexcept {
  stop_.store(true, std::memory_order_release);
  const uint64_t one = 1;
  if (control_event_ >= 0) (void)::write(control_event_, &one, sizeof one);
}

void TcpSensorLink::close() noexcept {
  for (const int fd : {data_event_, control_event_}) {
    if (fd < 0) continue;
    rt::modeswitch::unregister_rt_device(fd);
    ::close(fd);
  }
  data_event_ = control_event_ = -1;
  connected_.store(false);
}

void TcpSensorLink::wake_reader() noexcept {
  const uint64_t one = 1;
  (void)::write(data_event_, &one, sizeof one);
}

void TcpSensorLink::request_reconnect() noexcept {
  reconnect_.store(true, std::memory_order_release);
  const uint64_t one = 1;
  (void)::write(control_event_, &one, sizeof one);
}

void TcpSensorLink::discard() noexcept {
  tail_.store(head_.load(std::memory_order_acquire), std::memory_order_release);
}

bool TcpSensorLink::sleep_interruptible(int64_t ns) noexcept {
  short revents = 0;
  (void)detail::wait_fd(control_event_, POLLIN, ns, revents);
  uint64_t v;
  (void)::read(control_event_, &v, sizeof v);
  return !stop_.load(std::memory_order_acquire);
}

int TcpSensorLink::connect_once() noexcept {
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const std::string port = std::to_string(config_.port);
  if (::getaddrinfo(config_.host.c_str(), port.c_str(), &hints, &res) != 0 || res == nullptr) return -1;
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    ::freeaddrinfo(res);
    return -1;
  }
  int r = ::connect(fd, res->ai_addr, res->ai_addrlen);
  ::freeaddrinfo(res);
  if (r != 0 && errno == EINPROGRESS) {
    short revents = 0;
    if (detail::wait_fd(fd, POLLOUT, config_.connect_timeout_ns, revents) > 0) {
      int err = 0;
      socklen_t len = sizeof err;
      ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
      r = err == 0 ? 0 : -1;
    }
  }
  if (r != 0) {
    ::close(fd);
    return -1;
  }
  const int on = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);  // greetings are small
  // Keepalive: a sensor whose cable was pulled never sends FIN.
  ::setsockopt(fd, SOL_SOCKET, SO_KEEPALIVE, &on, sizeof on);
  return fd;
}

void TcpSensorLink::push(const uint8_t* data, std::size_t n) noexcept {
  const uint64_t head = head_.load(std::memory_order_relaxed);
  const uint64_t tail = tail_.load(std::memory_order_acquire);
  const std::size_t room = capacity_ - static_cast<std::size_t>(head - tail);
  const std::size_t take = std::min(room, n);
  for (std::size_t i = 0; i < take;) {
    const std::size_t at = static_cast<std::size_t>((head + i) % capacity_);
    const std::size_t chunk = std::min(take - i, capacity_ - at);
    std::memcpy(ring_.get() + at, data + i, chunk);
    i += chunk;
  }
  head_.store(head + take, std::memory_order_release);
  if (take < n) dropped_.fetch_add(n - take, std::memory_order_relaxed);
  wake_reader();
}

void TcpSensorLink::run() noexcept {
  if (control_event_ < 0 || data_event_ < 0) return;  // not open()
  int64_t backoff = config_.min_backoff_ns;
  while (!stop_.load(std::memory_order_acquire)) {
    reconnect_.store(false, std::memory_order_relaxed);
    const int fd = connect_once();
    if (fd < 0) {
      failed_.fetch_add(1, std::memory_order_relaxed);
      if (!sleep_interruptible(backoff)) break;
      backoff = std::min(backoff * 2, config_.max_backoff_ns);
      continue;
    }
    backoff = config_.min_backoff_ns;
    bool ok = true;
    for (std::size_t done = 0; ok && done < config_.greeting.size();) {
      const ssize_t n = ::send(fd, config_.greeting.data() + done, config_.greeting.size() - done, MSG_NOSIGNAL);
      if (n > 0) {
        done += static_cast<std::size_t>(n);
      } else if (n < 0 && errno == EAGAIN) {
        short revents = 0;
        ok = detail::wait_fd(fd, POLLOUT, config_.connect_timeout_ns, revents) > 0;
      } else {
        ok = false;
      }
    }
    if (ok) {
      connects_.fetch_add(1, std::memory_order_relaxed);
      connected_.store(true, std::memory_order_release);
    }
    while (ok && !stop_.load(std::memory_order_acquire) && !reconnect_.load(std::memory_order_acquire)) {
      pollfd p[2] = {{fd, POLLIN, 0}, {control_event_, POLLIN, 0}};
      if (::poll(p, 2, -1) < 0 && errno != EINTR) break;
      if ((p[1].revents & POLLIN) != 0) {
        uint64_t v;
        (void)::read(control_event_, &v, sizeof v);
      }
      if ((p[0].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
        const ssize_t n = ::recv(fd, receive_.get(), kReceiveBytes, MSG_DONTWAIT);
        if (n > 0) {
          push(receive_.get(), static_cast<std::size_t>(n));
        } else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
          ok = false;
        }
      }
    }
    ::close(fd);
    if (connected_.exchange(false, std::memory_order_acq_rel)) {
      disconnects_.fetch_add(1, std::memory_order_relaxed);
      epoch_.fetch_add(1, std::memory_order_release);
      wake_reader();
    }
    if (stop_.load(std::memory_order_acquire)) break;
    if (!sleep_interruptible(backoff)) break;
  }
  connected_.store(false, std::memory_order_release);
}

IoResult TcpSensorLink::read(std::span<uint8_t> buf, int64_t timeout_ns) noexcept {
  IoResult r;
  if (!ring_) {
    r.status = IoStatus::kClosed;
    return r;
  }
  const int64_t deadline = rt::monotonic_ns() + timeout_ns;
  for (;;) {
    const uint64_t epoch = epoch_.load(std::memory_order_acquire);
    if (epoch != seen_epoch_) {
      seen_epoch_ = epoch;
      r.status = IoStatus::kClosed;
      return r;
    }
    const uint64_t tail = tail_.load(std::memory_order_relaxed);
    const uint64_t head = head_.load(std::memory_order_acquire);
    if (head != tail) {
      const std::size_t n = std::min<std::size_t>(buf.size(), static_cast<std::size_t>(head - tail));
      for (std::size_t i = 0; i < n;) {
        const std::size_t at = static_cast<std::size_t>((tail + i) % capacity_);
        const std::size_t chunk = std::min(n - i, capacity_ - at);
        std::memcpy(buf.data() + i, ring_.get() + at, chunk);
        i += chunk;
      }
      tail_.store(tail + n, std::memory_order_release);
      r.status = IoStatus::kOk;
      r.bytes = n;
      r.stamp_ns = rt::host_time_ns();
      return r;
    }
    const int64_t left = deadline - rt::monotonic_ns();
    if (left <= 0) {
      r.status = IoStatus::kTimeout;
      return r;
    }
    short revents = 0;
    const int w = detail::wait_fd(data_event_, POLLIN, left, revents);
    if (w > 0) {
      uint64_t v;
      (void)::read(data_event_, &v, sizeof v);
    } else if (w == 0) {
      r.status = IoStatus::kTimeout;
      return r;
    } else {
      r.error = -w;
      return r;
    }
  }
}

}  // namespace rack::devices
