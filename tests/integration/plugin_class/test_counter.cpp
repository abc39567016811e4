#include "test_counter.h"

namespace rack::test_counter {

TestCounter::TestCounter()
    : DataComponent(DataTaskMode::kPeriodic),
      step_(declare_int("step", 1, {.doc = "added to the count every period", .min = 1, .max = 1000})),
      peer_(declare_int("peer", 0, {.doc = "a raw TiMS address, published in 'peer'", .min = 0, .max = 4294967295.0})) {
}

HookResult TestCounter::loop() {
  CounterData d;
  d.count = count_.fetch_add(step_.get_int(), std::memory_order_relaxed) + step_.get_int();
  d.peer = static_cast<uint32_t>(peer_.get_int());
  publish(d, rt::host_time_ns());
  return HookResult::kOk;
}

CommandResult TestCounter::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != kReset) return CommandResult::kUnknown;
  if (!body.empty()) {
    reject_malformed(request, "RESET takes no body");
    return CommandResult::kHandled;
  }
  count_.store(0, std::memory_order_relaxed);
  reply(request, tims::msg::kOk);
  return CommandResult::kHandled;
}

}  // namespace rack::test_counter
