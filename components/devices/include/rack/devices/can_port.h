// CanPort: classical CAN frames (struct can_frame) over SocketCAN raw sockets.
//
// Three ways to open, one read/write path:
//   open_socketcan("can0")     AF_CAN/SOCK_RAW/CAN_RAW bound to an interface (real
//                              buses, vcan); error frames enabled; kernel filters.
//   open_unix("/run/x.can")    an AF_UNIX SOCK_SEQPACKET connection to a peer that
//                              carries one struct can_frame per packet (the shipped
//                              CiA 402 simulator listens like this), for machines
//                              without CAN support.
//   adopt(fd)                  any datagram or seqpacket socket carrying struct
//                              can_frame (e.g. one end of a socketpair; tests).
// Everything after opening (receive with timeout, timestamps, filters, error frames,
// bus-off tracking, send) is the same code on every kind of socket: recvmsg/sendmsg
// of 16-byte frames. Filters are applied by the kernel on AF_CAN and by receive()
// otherwise, with SocketCAN's semantics (id & mask == filter id & mask).
//
// Bus-off: the controller reports it with an error frame (CAN_ERR_BUSOFF); the port
// then refuses to send (IoStatus::kError, ENETDOWN) until the controller reports
// CAN_ERR_RESTARTED or a frame is received again. Restart itself belongs to the
// interface (`ip link set can0 type can restart-ms 100`): netlink is not RT.
//
// Receive timestamps: SO_TIMESTAMPNS, the kernel's software receive time in the host
// clock (CLOCK_REALTIME ns), on AF_CAN and AF_UNIX alike; host_time_ns() after
// the read when the socket gives none.
//
// Real-time contract: open_*(), adopt(), set_filters() and close() are not RT-safe
// (socket set-up; call them from init()/on()/off()). receive(), send() and the
// accessors are RT-safe: one ppoll and one recvmsg/sendmsg, no allocation. One
// thread receives; one thread (the same or another) sends.
#pragma once

#include <linux/can.h>
#include <linux/can/error.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <span>
#include <string>

#include "rack/devices/io_status.h"

namespace rack::devices {

enum class CanKind : uint8_t { kNone, kSocketCan, kOther };

struct CanCounters {
  uint64_t received = 0;  // data frames delivered by receive()
  uint64_t sent = 0;
  uint64_t error_frames = 0;  // CAN_ERR_FLAG frames seen
  uint64_t bus_off = 0;       // bus-off events
  uint64_t filtered = 0;      // frames dropped by the software filter
  uint64_t malformed = 0;     // packets that were not one struct can_frame
  uint64_t send_failed = 0;   // ENOBUFS (tx queue full), bus-off, other errors
};

// Why opening failed, in a fixed buffer: the open path fills it without allocating,
// so a driver that opens its bus in on() (the command task) can fail and retry every
// second without leaving real time.
struct CanError {
  char text[160] = {};
};

class CanPort {
 public:
  static constexpr std::size_t kMaxFilters = 16;

  CanPort() = default;
  ~CanPort();
  CanPort(const CanPort&) = delete;
  CanPort& operator=(const CanPort&) = delete;

  // Not RT-safe (blocking set-up system calls, in a DeviceSetupScope). false with
  // `error` naming the interface/path and the errno text. The CanError forms allocate
  // nothing, failures included; the std::string forms copy the text.
  [[nodiscard]] bool open_socketcan(const char* ifname, CanError& error) noexcept;
  [[nodiscard]] bool open_unix(const char* path, CanError& error) noexcept;
  // "vcan0" or "unix:/path": the form host files use.
  [[nodiscard]] bool open(const char* spec, CanError& error) noexcept;
  [[nodiscard]] bool open_socketcan(const char* ifname, std::string& error);
  [[nodiscard]] bool open_unix(const char* path, std::string& error);
  [[nodiscard]] bool open(const char* spec, std::string& error);
  // Takes ownership of `fd`. Not RT-safe.
  void adopt(int fd);
  void close() noexcept;
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  [[nodiscard]] int fd() const noexcept { return fd_; }
  [[nodiscard]] CanKind kind() const noexcept { return kind_; }

  // Accept only frames matching one of these (empty: all). Error frames always pass.
  // Not RT-safe (setsockopt on AF_CAN). false when more than kMaxFilters.
  [[nodiscard]] bool set_filters(std::span<const can_filter> filters, CanError& error) noexcept;
  [[nodiscard]] bool set_filters(std::span<const can_filter> filters, std::string& error);

  // Waits up to timeout_ns for a data frame. Error frames update the bus state and
  // counters and are returned as kOk with CAN_ERR_FLAG set in can_id, so the caller
  // can log them. IoResult::stamp_ns is the receive time. RT-safe.
  IoResult receive(can_frame& frame, int64_t timeout_ns) noexcept;
  // Sends one frame without blocking. kError with ENOBUFS when the tx queue is
  // full, ENETDOWN while bus-off. RT-safe.
  IoResult send(const can_frame& frame) noexcept;

  [[nodiscard]] bool bus_off() const noexcept { return bus_off_.load(std::memory_order_relaxed); }
  // Error passive (TX or RX error counter above 127), from the last controller error frame.
  [[nodiscard]] bool error_passive() const noexcept { return error_passive_; }
  // Counters; the receiving thread writes them (relaxed reads elsewhere are fine: statistics).
  [[nodiscard]] const CanCounters& counters() const noexcept { return counters_; }

 private:
  [[nodiscard]] bool accepted(canid_t id) const noexcept;
  void handle_error_frame(const can_frame& f) noexcept;
  bool configure_common(CanError& error) noexcept;
  // Makes `fd` this port's descriptor (registered as an RT device for mode-switch
  // detection) and applies the common options; on failure `error` says why.
  bool take(int fd, CanKind kind, CanError& error, bool close_on_failure) noexcept;

  int fd_ = -1;
  CanKind kind_ = CanKind::kNone;
  std::array<can_filter, kMaxFilters> filters_{};
  std::size_t filter_count_ = 0;
  // Written by the receiving thread, read by the sending one: relaxed, a stale view
  // costs one frame that the kernel would refuse anyway.
  std::atomic<bool> bus_off_{false};
  bool error_passive_ = false;
  CanCounters counters_;
  alignas(8) char control_[64] = {};  // recvmsg control buffer (timestamps), preallocated
};

// Frame helpers. RT-safe.
[[nodiscard]] can_frame make_frame(canid_t id, std::span<const uint8_t> data) noexcept;

}  // namespace rack::devices
