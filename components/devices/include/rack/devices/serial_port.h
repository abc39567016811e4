// SerialPort: a tty (UART, USB-serial, USB-ACM, or a pseudo-terminal) in raw mode.
//
// open() configures raw 8N1, no flow control, the given baud rate, and asks the
// driver for low-latency mode (ASYNC_LOW_LATENCY: on USB-serial this cuts the
// 16 ms latency timer of FTDI chips to 1 ms). Drivers that do not support it (ptys,
// USB-ACM) are not an error: low_latency() says whether it took.
//
// Receive timestamps: ttys carry no kernel timestamps, so a read is stamped with the
// host clock right after poll() reports data. At 115200 baud one byte is ~87 us, so
// the stamp lags the first byte by at most the bytes already queued; drivers that
// need better correct for the frame length.
//
// Real-time contract: open() and close() are not RT-safe (open, ioctl, tcsetattr;
// call them from init()/on()/off(), never from loop()); read(), write_all() and
// flush_input() are RT-safe: only poll/read/write/tcflush on the open fd, no
// allocation. One thread reads; writes may come from one other thread.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "rack/devices/io_status.h"

namespace rack::devices {

class SerialPort {
 public:
  SerialPort() = default;
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  // Opens and configures `path`. false with `error` naming the path and errno text.
  // Baud rates: 1200 ... 4000000 (the termios Bxxx set). Not RT-safe.
  [[nodiscard]] bool open(const char* path, int baud, std::string& error);
  // Same, for RT hooks (on()): `error` is a caller buffer, nothing allocates.
  [[nodiscard]] bool open(const char* path, int baud, char* error, std::size_t error_size) noexcept;
  void close() noexcept;
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  [[nodiscard]] int fd() const noexcept { return fd_; }
  [[nodiscard]] bool low_latency() const noexcept { return low_latency_; }

  // Reads what is available (up to buf.size()), waiting up to timeout_ns for the
  // first byte (0: do not wait). RT-safe.
  IoResult read(std::span<uint8_t> buf, int64_t timeout_ns) noexcept;
  // Writes all bytes, waiting up to timeout_ns in total for the tty to take them. RT-safe.
  IoResult write_all(std::span<const uint8_t> data, int64_t timeout_ns) noexcept;
  // Drops unread input (after a resync). RT-safe.
  void flush_input() noexcept;

  // The termios speed constant for a baud rate; 0 when unsupported. RT-safe.
  [[nodiscard]] static unsigned speed_constant(int baud) noexcept;

 private:
  int fd_ = -1;
  bool low_latency_ = false;
};

}  // namespace rack::devices
