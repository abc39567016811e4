// The Linux joystick API's event stream (/dev/input/jsN: struct js_event, 8 bytes each),
// decoded into JoystickData: axes scaled to [-1, 1], buttons as a bit mask. A plain
// decoder of bytes, apart from the device, so that tests/fuzz/fuzz_joystick.cpp drives
// it as Joystick::loop() does (reads of any size, events split across reads).
//
// Bad input: an unknown event type, an axis number >= kJoystickMaxAxes, a button number
// >= 32 or a button value other than 0/1 is counted in bad_events and changes nothing
// else. The axis value -32768 (a FIFO or a broken driver can send it; the kernel's
// range is -32767..32767) reads as -1.
//
// Real-time contract: RT-safe (no allocation, no system call); one thread per decoder.
#pragma once

#include <linux/joystick.h>

#include <array>
#include <cstddef>
#include <cstdint>

#include "joystick_types.h"

namespace rack::components {

// Applies one event to `state` (events or bad_events counted).
void apply_js_event(const js_event& e, interfaces::JoystickData& state) noexcept;

// Reassembles events from reads of any size: read() into space() (space_size() bytes at
// most), then received(n); a partial event waits for the next read.
class JsEventDecoder {
 public:
  [[nodiscard]] uint8_t* space() noexcept { return buffer_.data() + pending_; }
  [[nodiscard]] std::size_t space_size() const noexcept { return buffer_.size() - pending_; }
  // n (<= space_size()) bytes were read into space(): applies every complete event.
  void received(std::size_t n, interfaces::JoystickData& state) noexcept;
  // Drops a partial event (the device was opened again).
  void reset() noexcept { pending_ = 0; }
  [[nodiscard]] std::size_t pending() const noexcept { return pending_; }

 private:
  std::array<uint8_t, sizeof(js_event) * 32> buffer_{};
  std::size_t pending_ = 0;  // bytes of an incomplete event carried to the next read
};

}  // namespace rack::components
