// Results of device I/O calls, shared by SerialPort, CanPort and TcpSensorLink.
//
// Real-time contract: plain data; describe() is RT-safe.
#pragma once

#include <cstddef>
#include <cstdint>

namespace rack::devices {

enum class IoStatus : uint8_t {
  kOk,       // data moved
  kTimeout,  // nothing within the timeout
  kClosed,   // the device went away (EOF, hang-up, peer closed): reopen it
  kError,    // another error; errno in IoResult::error
};
[[nodiscard]] const char* describe(IoStatus s) noexcept;

struct IoResult {
  IoStatus status = IoStatus::kError;
  std::size_t bytes = 0;
  int error = 0;         // errno when status is kError / kClosed
  int64_t stamp_ns = 0;  // receive time, host clock (CLOCK_REALTIME ns); 0 when nothing came
};

}  // namespace rack::devices
