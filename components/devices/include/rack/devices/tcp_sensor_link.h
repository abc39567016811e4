// TcpSensorLink: a TCP connection to a sensor (SICK scanners, GNSS receivers with an
// Ethernet port) kept up by run() in a non-RT thread, read by an RT task without
// blocking. The link makes no thread: in rackd, run() is an I/O worker of the
// component (Component::add_io_worker), in an executor-owned non-RT thread placed on
// the housekeeping CPUs; a test may run it in a thread of its own.
//
// run() connects (with a timeout), sends the configured greeting (e.g. a
// CoLa-A "start continuous output" telegram) after every connect, and copies what
// arrives into a preallocated single-producer/single-consumer byte ring. When the
// peer closes, the connection fails or the RT side asks for it (request_reconnect(),
// e.g. after a watchdog timeout), it reconnects with exponential back-off
// (min_backoff_ns doubling up to max_backoff_ns, reset by a successful connect).
// Bytes that do not fit in the ring are dropped and counted (the RT side is too
// slow; it must resynchronise on the protocol's frame markers).
//
// Real-time contract: open(), run() and close() are not RT-safe (they allocate, block
// on the socket, close descriptors: init(), the I/O worker, cleanup()). read(),
// connected(), request_reconnect(), request_stop() and the counters are RT-safe: the RT
// side only polls an eventfd and copies from the ring. Single consumer: one RT thread
// calls read(); one thread calls run().
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "rack/devices/io_status.h"

namespace rack::devices {

struct TcpSensorConfig {
  std::string host = "127.0.0.1";  // IPv4 address or name (resolved by the link thread)
  uint16_t port = 0;
  std::vector<uint8_t> greeting;  // sent after every connect
  std::size_t ring_bytes = 256 * 1024;
  int64_t connect_timeout_ns = 1'000'000'000;
  int64_t min_backoff_ns = 100'000'000;
  int64_t max_backoff_ns = 5'000'000'000;
};

class TcpSensorLink {
 public:
  TcpSensorLink() = default;
  ~TcpSensorLink();
  TcpSensorLink(const TcpSensorLink&) = delete;
  TcpSensorLink& operator=(const TcpSensorLink&) = delete;

  // Allocates the ring and the eventfds (not RT-safe). Throws std::system_error when
  // it cannot make the eventfds.
  void open(TcpSensorConfig config);
  // The link loop: connects, reads into the ring, reconnects; returns once
  // request_stop() was called (within a poll wake-up). Blocks: a non-RT thread only.
  void run() noexcept;
  // Makes run() return (and a later run() return at once). RT-safe, any thread.
  void request_stop() noexcept;
  // Closes the eventfds; call when run() has returned (or never ran). Not RT-safe.
  void close() noexcept;

  // Copies up to buf.size() buffered bytes, waiting up to timeout_ns when the ring is
  // empty. kTimeout when nothing arrived. kClosed (with nothing read) once after each
  // lost connection, so the driver can resynchronise. RT-safe.
  IoResult read(std::span<uint8_t> buf, int64_t timeout_ns) noexcept;
  // Drops the connection and connects again (after the back-off). RT-safe.
  void request_reconnect() noexcept;
  // Drops what is buffered (after a resync or on()). RT-safe, consumer only.
  void discard() noexcept;

  [[nodiscard]] bool connected() const noexcept { return connected_.load(std::memory_order_acquire); }
  [[nodiscard]] uint64_t connects() const noexcept { return connects_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t disconnects() const noexcept { return disconnects_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t dropped_bytes() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t failed_connects() const noexcept { return failed_.load(std::memory_order_relaxed); }

 private:
  int connect_once() noexcept;  // fd or -1
  void push(const uint8_t* data, std::size_t n) noexcept;
  void wake_reader() noexcept;
  bool sleep_interruptible(int64_t ns) noexcept;  // false when stopping

  TcpSensorConfig config_;
  std::unique_ptr<uint8_t[]> ring_;
  static constexpr std::size_t kReceiveBytes = 16 * 1024;
  std::unique_ptr<uint8_t[]> receive_;  // run()'s recv() buffer (allocated by open())
  std::size_t capacity_ = 0;
  // SYNC POINT: the link thread writes bytes then head_ (release); the reader loads
  // head_ (acquire) then reads the bytes, and publishes tail_ (release) after copying
  // so the writer (acquire) never overwrites unread bytes.
  std::atomic<uint64_t> head_{0};
  std::atomic<uint64_t> tail_{0};
  // Lost-connection marker: bumped by the link thread, compared by the reader.
  std::atomic<uint64_t> epoch_{0};
  uint64_t seen_epoch_ = 0;
  int data_event_ = -1;     // eventfd: the link thread -> reader ("bytes or epoch changed")
  int control_event_ = -1;  // eventfd: reader/stop() -> link thread
  std::atomic<bool> stop_{false};
  std::atomic<bool> reconnect_{false};
  std::atomic<bool> connected_{false};
  std::atomic<uint64_t> connects_{0}, disconnects_{0}, dropped_{0}, failed_{0};
};

}  // namespace rack::devices
