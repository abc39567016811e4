// The task timeline: per-task rings of timestamped events (wake-up, start and end of
// each cycle, overruns, mode switches, message hand-offs) that a non-RT thread drains
// and writes as a Chrome/Perfetto trace (rack/core/trace_session.h).
//
// Each task owns one Ring, bound to its thread with bind_thread_ring() before its
// first cycle. The hooks (record(), the inline functions below) look up the calling
// thread's ring; with no ring bound, or the ring switched off, they return after two
// loads (a thread-local pointer and a relaxed atomic flag): tracing off costs nothing
// measurable (bench_trace). Switched on, a hook reads the clock once and writes 32
// bytes into preallocated memory.
//
// Real-time contract: record*, active(), Ring::try_push, enabled() are RT-safe (no
// allocation, no lock, no system call besides clock_gettime's vDSO).
// bind_thread_ring() makes one gettid system call: call it at task start-up.
// The Ring constructor allocates (not RT-safe: call at start-up).
// Thread-safety: Ring is single-producer (the task it is bound to) single-consumer
// (the draining thread): "restricted thread-safe". set_enabled() from any thread.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>

namespace rack::rt::trace {

enum class Kind : uint8_t {
  kNone = 0,
  kWake,        // a periodic task woke up; value: the time it was due (ns)
  kCycleStart,  // loop() or a command handler starts
  kCycleEnd,    // it ended; value: 0 ok, 1 failed
  kOverrun,     // value: periods missed
  kModeSwitch,  // value: mode-switch reports recorded during the cycle
  kSend,        // a message left this task; peer: destination, aux: type and seq
  kReceive,     // a message reached this task; peer: source, aux: type and seq
};
[[nodiscard]] const char* kind_name(Kind k) noexcept;

struct Event {
  int64_t time_ns = 0;  // CLOCK_MONOTONIC
  int64_t value = 0;    // per Kind
  uint32_t peer = 0;    // TiMS address (kSend, kReceive)
  uint16_t aux = 0;     // kSend/kReceive: (uint8 type << 8) | seq
  Kind kind = Kind::kNone;
  uint8_t reserved = 0;
  uint32_t self = 0;  // kSend: the message's source; kReceive: its destination
};
static_assert(sizeof(Event) == 32);

[[nodiscard]] constexpr uint16_t message_aux(int8_t type, uint8_t seq) noexcept {
  return static_cast<uint16_t>((static_cast<uint16_t>(static_cast<uint8_t>(type)) << 8) | seq);
}
[[nodiscard]] constexpr int8_t aux_type(uint16_t aux) noexcept { return static_cast<int8_t>(aux >> 8); }
[[nodiscard]] constexpr uint8_t aux_seq(uint16_t aux) noexcept { return static_cast<uint8_t>(aux & 0xFF); }

// A bounded single-producer single-consumer ring of Events. A push into a full ring
// is dropped and counted (the task never waits for the drainer).
class Ring {
 public:
  // capacity: rounded up to a power of two, at least 2. Allocates: not RT-safe.
  explicit Ring(std::size_t capacity);
  Ring(const Ring&) = delete;
  Ring& operator=(const Ring&) = delete;

  [[nodiscard]] std::size_t capacity() const noexcept { return mask_ + 1; }
  // Relaxed: a hook that sees the switch a few cycles late records a few events more
  // or fewer; nothing else is published through this flag.
  [[nodiscard]] bool enabled() const noexcept { return enabled_.load(std::memory_order_relaxed); }
  void set_enabled(bool on) noexcept { enabled_.store(on, std::memory_order_relaxed); }

  // Producer only. False (and counted) when full. RT-safe.
  bool try_push(const Event& e) noexcept;
  // Consumer only: moves up to out.size() events out, oldest first; returns how many.
  std::size_t drain(std::span<Event> out) noexcept;
  // Events pushed and events dropped since construction (any thread).
  [[nodiscard]] uint64_t pushed() const noexcept { return pushed_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  // The Linux thread id of the task bound to it (0 until bound).
  [[nodiscard]] int tid() const noexcept { return tid_.load(std::memory_order_relaxed); }

 private:
  friend void bind_thread_ring(Ring* ring) noexcept;
  std::unique_ptr<Event[]> events_;
  std::size_t mask_;
  // SYNC POINT: the producer writes the slot, then publishes head_ (release); the
  // consumer reads head_ (acquire) before it reads the slot.
  alignas(64) std::atomic<uint64_t> head_{0};
  // SYNC POINT: the consumer has read the slots before it publishes tail_ (release);
  // the producer reads tail_ (acquire) before it reuses a slot.
  alignas(64) std::atomic<uint64_t> tail_{0};
  std::atomic<uint64_t> pushed_{0};   // relaxed: counters only
  std::atomic<uint64_t> dropped_{0};  // relaxed: counters only
  std::atomic<bool> enabled_{false};
  std::atomic<int> tid_{0};
};

namespace detail {
extern thread_local Ring* t_ring;
void record_slow(Ring& ring, Kind kind, int64_t value, uint32_t peer, uint16_t aux, uint32_t self) noexcept;
void record_at_slow(Ring& ring, int64_t time_ns, Kind kind, int64_t value) noexcept;
}  // namespace detail

// Binds `ring` (nullptr: none) to the calling thread and notes its thread id (one
// gettid call: at task start-up, before the first cycle).
void bind_thread_ring(Ring* ring) noexcept;
[[nodiscard]] inline Ring* thread_ring() noexcept { return detail::t_ring; }
// True when the calling thread records now (lets a hook skip work such as reading a header).
[[nodiscard]] inline bool active() noexcept {
  Ring* r = detail::t_ring;
  return r != nullptr && r->enabled();
}

// Records an event stamped now into the calling thread's ring (if any, if on). RT-safe.
inline void record(Kind kind, int64_t value = 0, uint32_t peer = 0, uint16_t aux = 0, uint32_t self = 0) noexcept {
  Ring* r = detail::t_ring;
  if (r != nullptr && r->enabled()) detail::record_slow(*r, kind, value, peer, aux, self);
}
// Records an event with a time the caller already read (saves a clock read). RT-safe.
inline void record_at(int64_t time_ns, Kind kind, int64_t value = 0) noexcept {
  Ring* r = detail::t_ring;
  if (r != nullptr && r->enabled()) detail::record_at_slow(*r, time_ns, kind, value);
}

}  // namespace rack::rt::trace
