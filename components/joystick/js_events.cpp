#include "js_events.h"

#include <algorithm>
#include <cstring>

namespace rack::components {

using interfaces::kJoystickMaxAxes;

void apply_js_event(const js_event& e, interfaces::JoystickData& state) noexcept {
  const uint8_t type = e.type & static_cast<uint8_t>(~JS_EVENT_INIT);  // INIT: the state at open
  if (type == JS_EVENT_AXIS && e.number < kJoystickMaxAxes) {
    // -32768 (a FIFO or a broken driver; the kernel reports -32767..32767) is -1, not below it.
    state.axis[e.number] = std::max(-1.0F, static_cast<float>(e.value) / 32767.0F);
    if (e.number + 1U > state.axis_count) state.axis_count = e.number + 1U;
  } else if (type == JS_EVENT_BUTTON && e.number < 32 && (e.value == 0 || e.value == 1)) {
    const uint32_t bit = 1U << e.number;
    state.buttons = e.value != 0 ? (state.buttons | bit) : (state.buttons & ~bit);
    if (e.number + 1U > state.button_count) state.button_count = e.number + 1U;
  } else {
    ++state.bad_events;
    return;
  }
  ++state.events;
}

void JsEventDecoder::received(std::size_t n, interfaces::JoystickData& state) noexcept {
  const std::size_t have = pending_ + (n < space_size() ? n : space_size());
  std::size_t at = 0;
  for (; at + sizeof(js_event) <= have; at += sizeof(js_event)) {
    js_event e;
    std::memcpy(&e, buffer_.data() + at, sizeof e);
    apply_js_event(e, state);
  }
  pending_ = have - at;
  if (pending_ > 0) std::memmove(buffer_.data(), buffer_.data() + at, pending_);
}

}  // namespace rack::components
