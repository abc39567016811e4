// libFuzzer harness for the joystick's event stream (components/joystick/js_events.cpp:
// JsEventDecoder, apply_js_event), the bytes Joystick::loop() reads from /dev/input/jsN
// or a FIFO (rack-devsim joystick --fifo): any device or writer can send anything.
//
// Input: byte 0 sets the size of the reads (1..64 bytes); the rest is the stream, in
// reads of that size as loop() gets them. Properties: every complete 8-byte record is
// counted once, as an event or a bad event; axes are finite and in [-1, 1] (as
// JoystickData says); the axis and button counts stay within the arrays and no button
// bit is set at or above the button count; a partial record waits, shorter than one.
//
// Seeds: tests/fuzz/corpus/joystick/ (the INIT burst of a two-axis, four-button pad,
// then moves and presses; the same cut mid-event).
#include <linux/joystick.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "fuzz_support.h"
#include "js_events.h"

using rack::components::JsEventDecoder;
using rack::interfaces::JoystickData;
using rack::interfaces::kJoystickMaxAxes;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const std::size_t piece = 1 + in.byte() % 64;
  JsEventDecoder decoder;
  JoystickData state{};
  std::size_t fed = 0;
  while (!in.empty()) {
    const auto read = in.bytes(std::min(piece, decoder.space_size()));
    std::memcpy(decoder.space(), read.data(), read.size());
    decoder.received(read.size(), state);
    fed += read.size();
    FUZZ_CHECK(decoder.pending() < sizeof(js_event));
    FUZZ_CHECK(state.events + state.bad_events == (fed - decoder.pending()) / sizeof(js_event));
    FUZZ_CHECK(state.axis_count <= kJoystickMaxAxes && state.button_count <= 32);
    FUZZ_CHECK(state.button_count == 32 || (state.buttons >> state.button_count) == 0);
    for (const float a : state.axis) FUZZ_CHECK(std::isfinite(a) && a >= -1.0F && a <= 1.0F);
  }
  return 0;
}
