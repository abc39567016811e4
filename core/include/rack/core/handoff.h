// Handoff<T>: the one way a command (command task) hands work to the data task.
//
// The command task post()s: it changes the pending value under a PI mutex (a
// request overwrites the one before it, or a count adds up: the caller's update
// says which). The data task take()s it at the start of its next loop(): it gets the
// pending value and the slot is empty again. Nothing is queued, so a burst of
// commands costs no memory, and the data task never waits longer than one short
// critical section (priority inheritance: a low-priority command task holding the
// lock is boosted).
//
//   Handoff<interfaces::MclInit> init_;                    // member
//   init_.post(request);                                   // command(): the newest wins
//   reset_.post([](uint32_t& n) { ++n; });                 // command(): requests add up
//   if (interfaces::MclInit i; init_.take(i)) apply(i);    // loop()
//
// A triggered data task runs loop() only when input arrives: after a post() that
// loop() should see at once (a request it answers), the command task also calls
// DataComponentBase::wake_loop(). A value the data task keeps using (a velocity set
// point) is taken into the data task's own copy: `(void)velocity_.take(current_)`.
//
// Real-time contract: post(), take(), pending() and clear() are RT-safe (no
// allocation; a PI mutex held for a copy of T) from any task. T must be copyable
// without allocating (a trivially copyable payload, a number).
#pragma once

#include <type_traits>

#include "rack/rt/pi_mutex.h"

namespace rack {

template <typename T>
class Handoff {
  static_assert(std::is_trivially_copyable_v<T>, "a Handoff's value is copied in the data task: no allocation");

 public:
  // Command task: `value` replaces what is pending.
  void post(const T& value) noexcept {
    rt::PiLock lock(mutex_);
    value_ = value;
    pending_ = true;
  }
  // Command task: `update(T&)` changes the pending value (a fresh T{} when none is
  // pending), e.g. to count requests. `update` must not block or allocate.
  template <typename Update>
  requires std::is_invocable_v<Update, T&>
  void post(Update&& update) noexcept {
    rt::PiLock lock(mutex_);
    if (!pending_) value_ = T{};
    update(value_);
    pending_ = true;
  }
  // Data task: moves the pending value into `out`; false (out untouched) when none.
  [[nodiscard]] bool take(T& out) noexcept {
    rt::PiLock lock(mutex_);
    if (!pending_) return false;
    out = value_;
    pending_ = false;
    return true;
  }
  [[nodiscard]] bool pending() const noexcept {
    rt::PiLock lock(mutex_);
    return pending_;
  }
  // Drops what is pending (on(): requests made while OFF do not count).
  void clear() noexcept {
    rt::PiLock lock(mutex_);
    pending_ = false;
  }

 private:
  mutable rt::PiMutex mutex_;
  T value_{};
  bool pending_ = false;
};

}  // namespace rack
