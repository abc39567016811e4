#include "rack/devices/serial_port.h"
#include "rack/rt/input_file.h"
#include "rack/rt/modeswitch.h"

#include <fcntl.h>
#include <linux/serial.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "poll_util.h"
#include "rack/rt/clock.h"

namespace rack::devices {

SerialPort::~SerialPort() { close(); }

unsigned SerialPort::speed_constant(int baud) noexcept {
  switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 576000: return B576000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 1500000: return B1500000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return 0;
  }
}

bool SerialPort::open(const char* path, int baud, std::string& error) {
  char buf[256];
  if (open(path, baud, buf, sizeof buf)) return true;
  error = buf;
  return false;
}

bool SerialPort::open(const char* path, int baud, char* error, std::size_t error_size) noexcept {
  const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
  close();
  const unsigned speed = speed_constant(baud);
  if (speed == 0) {
    std::snprintf(error, error_size, "%s: unsupported baud rate %d", path, baud);
    return false;
  }
  // A serial port is a character device (a tty, a USB adapter, a pty of a simulator): a
  // regular file or FIFO named by mistake is refused here with what it is. When stat()
  // fails, open() below says why.
  struct stat st {};
  if (::stat(path, &st) == 0 && !S_ISCHR(st.st_mode)) {
    std::snprintf(error, error_size, "%s: the serial port is %s, not a character device (a tty)", path,
                  rt::file_kind_text(st.st_mode));
    return false;
  }
  // O_NOCTTY: a serial sensor must never become our controlling terminal;
  // O_NONBLOCK: reads are driven by poll() with a timeout, never block in read().
  const int fd = ::open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    std::snprintf(error, error_size, "%s: open: %s", path, std::strerror(errno));
    return false;
  }
  termios t{};
  if (::tcgetattr(fd, &t) != 0) {
    std::snprintf(error, error_size, "%s: not a tty: %s", path, std::strerror(errno));
    ::close(fd);
    return false;
  }
  ::cfmakeraw(&t);
  t.c_cflag |= CLOCAL | CREAD;  // ignore modem lines: sensors rarely wire DCD
  t.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS);
  t.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  t.c_cc[VMIN] = 0;
  t.c_cc[VTIME] = 0;
  ::cfsetispeed(&t, speed);
  ::cfsetospeed(&t, speed);
  if (::tcsetattr(fd, TCSANOW, &t) != 0) {
    std::snprintf(error, error_size, "%s: tcsetattr (baud %d): %s", path, baud, std::strerror(errno));
    ::close(fd);
    return false;
  }
  low_latency_ = false;
  serial_struct ss{};
  if (::ioctl(fd, TIOCGSERIAL, &ss) == 0) {
    ss.flags = static_cast<int>(static_cast<unsigned>(ss.flags) | ASYNC_LOW_LATENCY);
    low_latency_ = ::ioctl(fd, TIOCSSERIAL, &ss) == 0;
  }
  ::tcflush(fd, TCIOFLUSH);  // stale bytes from before we opened are not this session's
  fd_ = fd;
  (void)rt::modeswitch::register_rt_device(fd_);  // RT tasks read, write and poll on it
  return true;
}

void SerialPort::close() noexcept {
  const rt::modeswitch::DeviceSetupScope setup;  // opening blocks: deliberate set-up in on()
  if (fd_ >= 0) {
    rt::modeswitch::unregister_rt_device(fd_);
    ::close(fd_);
  }
  fd_ = -1;
  low_latency_ = false;
}

IoResult SerialPort::read(std::span<uint8_t> buf, int64_t timeout_ns) noexcept {
  IoResult r;
  if (fd_ < 0) {
    r.status = IoStatus::kClosed;
    r.error = EBADF;
    return r;
  }
  short revents = 0;
  const int w = detail::wait_fd(fd_, POLLIN, timeout_ns, revents);
  if (w == 0) {
    r.status = IoStatus::kTimeout;
    return r;
  }
  if (w < 0) {
    r.error = -w;
    return r;
  }
  r.stamp_ns = rt::host_time_ns();
  const ssize_t n = ::read(fd_, buf.data(), buf.size());
  if (n > 0) {
    r.status = IoStatus::kOk;
    r.bytes = static_cast<std::size_t>(n);
    return r;
  }
  // A pty whose master closed reads EIO; a USB adapter unplugged reads 0 or EIO
  // with POLLHUP: either way the device is gone.
  if (n == 0 || errno == EIO || (revents & (POLLHUP | POLLERR | POLLNVAL)) != 0) {
    r.status = IoStatus::kClosed;
    r.error = n == 0 ? 0 : errno;
    return r;
  }
  if (errno == EAGAIN || errno == EINTR) {
    r.status = IoStatus::kTimeout;
    return r;
  }
  r.error = errno;
  return r;
}

IoResult SerialPort::write_all(std::span<const uint8_t> data, int64_t timeout_ns) noexcept {
  IoResult r;
  if (fd_ < 0) {
    r.status = IoStatus::kClosed;
    r.error = EBADF;
    return r;
  }
  const int64_t deadline = rt::monotonic_ns() + timeout_ns;
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd_, data.data() + done, data.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      r.status = errno == EIO ? IoStatus::kClosed : IoStatus::kError;
      r.error = errno;
      r.bytes = done;
      return r;
    }
    short revents = 0;
    const int64_t left = deadline - rt::monotonic_ns();
    if (left <= 0 || detail::wait_fd(fd_, POLLOUT, left, revents) <= 0) {
      r.status = IoStatus::kTimeout;
      r.bytes = done;
      return r;
    }
  }
  r.status = IoStatus::kOk;
  r.bytes = done;
  return r;
}

void SerialPort::flush_input() noexcept {
  if (fd_ >= 0) ::tcflush(fd_, TCIFLUSH);
}

}  // namespace rack::devices
