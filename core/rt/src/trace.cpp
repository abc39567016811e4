#include "rack/rt/trace.h"

#include <sys/syscall.h>
#include <unistd.h>

#include "rack/rt/clock.h"

namespace rack::rt::trace {

namespace detail {
thread_local Ring* t_ring = nullptr;

void record_slow(Ring& ring, Kind kind, int64_t value, uint32_t peer, uint16_t aux, uint32_t self) noexcept {
  Event e;
  e.time_ns = monotonic_ns();
  e.value = value;
  e.peer = peer;
  e.aux = aux;
  e.self = self;
  e.kind = kind;
  (void)ring.try_push(e);
}

void record_at_slow(Ring& ring, int64_t time_ns, Kind kind, int64_t value) noexcept {
  Event e;
  e.time_ns = time_ns;
  e.value = value;
  e.kind = kind;
  (void)ring.try_push(e);
}
}  // namespace detail

const char* kind_name(Kind k) noexcept {
  switch (k) {
    case Kind::kNone: return "none";
    case Kind::kWake: return "wake";
    case Kind::kCycleStart: return "cycle start";
    case Kind::kCycleEnd: return "cycle end";
    case Kind::kOverrun: return "overrun";
    case Kind::kModeSwitch: return "mode switch";
    case Kind::kSend: return "send";
    case Kind::kReceive: return "receive";
  }
  return "?";
}

namespace {
std::size_t round_up(std::size_t n) {
  std::size_t c = 2;
  while (c < n) c <<= 1;
  return c;
}
}  // namespace

Ring::Ring(std::size_t capacity) : events_(new Event[round_up(capacity)]), mask_(round_up(capacity) - 1) {}

bool Ring::try_push(const Event& e) noexcept {
  const uint64_t head = head_.load(std::memory_order_relaxed);  // only this thread writes it
  if (head - tail_.load(std::memory_order_acquire) > mask_) {
    dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);  // single writer
    return false;
  }
  events_[head & mask_] = e;
  head_.store(head + 1, std::memory_order_release);
  // Single writer: a plain load and store, no locked read-modify-write on the RT path.
  pushed_.store(pushed_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  return true;
}

std::size_t Ring::drain(std::span<Event> out) noexcept {
  const uint64_t tail = tail_.load(std::memory_order_relaxed);  // only this thread writes it
  const uint64_t head = head_.load(std::memory_order_acquire);
  std::size_t n = 0;
  for (uint64_t i = tail; i != head && n < out.size(); ++i) out[n++] = events_[i & mask_];
  tail_.store(tail + n, std::memory_order_release);
  return n;
}

void bind_thread_ring(Ring* ring) noexcept {
  detail::t_ring = ring;
  if (ring != nullptr) ring->tid_.store(static_cast<int>(syscall(SYS_gettid)), std::memory_order_relaxed);
}

}  // namespace rack::rt::trace
