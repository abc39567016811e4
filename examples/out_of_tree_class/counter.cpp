// Counter: a component class built outside RACK-RT's source tree against the
// installed SDK (find_package(rack), README "Writing a component class outside the
// tree"). It publishes a counter every period, takes a class command RESET (no body)
// and ADD (a body with one field), and has two parameters.
//
// The class's symbols (Component, DataComponent, Parameter, ...) are resolved against
// rackd when it loads this plug-in: the library links no rack library itself.
#include <array>
#include <atomic>
#include <cstring>
#include <memory>

#include "rack/core/class_types.h"
#include "rack/core/data_component.h"
#include "rack/core/registry.h"

namespace example {

// The sample type: a fixed layout with a field table (tools print it by name).
struct CounterData {
  int64_t count = 0;  // step per period since ON, RESET or ADD
  int64_t step = 0;   // the step parameter in effect
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(CounterData, count), RACK_FIELD(CounterData, step)};
  }
};

// ADD's body.
struct CounterAdd {
  int64_t amount = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(CounterAdd, amount)}; }
};

inline constexpr int8_t kCounterReset = 21;  // no body: count to `start`; reply OK
inline constexpr int8_t kCounterAdd = 22;    // CounterAdd: count += amount; reply OK

inline constexpr uint8_t kCounterClassId = 0x91;  // TiMS class of its addresses

class Counter final : public rack::DataComponent<CounterData> {
 public:
  Counter()
      : DataComponent(rack::DataTaskMode::kPeriodic),
        step_(declare_int("step", 1, {.doc = "added to the count every period", .min = -1000, .max = 1000})),
        start_(declare_int("start", 0, {.doc = "the count after ON and RESET"})) {}

 protected:
  rack::HookResult on() override {
    count_.store(start_.get_int(), std::memory_order_relaxed);
    return rack::HookResult::kOk;
  }

  // RT: no allocation, no lock, no system call.
  rack::HookResult loop() override {
    CounterData d;
    // Relaxed: count_ is this task's; RESET and ADD (command task) only need to land.
    d.step = step_.get_int();
    d.count = count_.fetch_add(d.step, std::memory_order_relaxed) + d.step;
    publish(d, rack::rt::host_time_ns());
    return rack::HookResult::kOk;
  }

  rack::CommandResult command(const rack::tims::MessageHeader& request, std::span<const std::byte> body) override {
    if (request.type == kCounterReset) {
      if (!body.empty()) {
        reject_malformed(request, "RESET takes no body");
        return rack::CommandResult::kHandled;
      }
      count_.store(start_.get_int(), std::memory_order_relaxed);
      reply(request, rack::tims::msg::kOk);
      return rack::CommandResult::kHandled;
    }
    if (request.type == kCounterAdd) {
      CounterAdd add;
      if (body.size() != sizeof add) {
        reject_malformed(request, "ADD takes an 8-byte body (amount)");
        return rack::CommandResult::kHandled;
      }
      std::memcpy(&add, body.data(), sizeof add);
      count_.fetch_add(add.amount, std::memory_order_relaxed);
      reply(request, rack::tims::msg::kOk);
      return rack::CommandResult::kHandled;
    }
    return rack::CommandResult::kUnknown;
  }

 private:
  rack::Parameter& step_;
  rack::Parameter& start_;
  std::atomic<int64_t> count_{0};
};

// What the class declares to tools: its data type and commands by name.
constexpr rack::DataTypeInfo kCounterDataInfo = rack::data_type_info<CounterData>("CounterData");
constexpr rack::DataTypeInfo kCounterAddInfo = rack::data_type_info<CounterAdd>("CounterAdd");
constexpr std::array kCounterCommands{
    rack::CommandInfo{"RESET", kCounterReset, nullptr, "count to the start parameter"},
    rack::CommandInfo{"ADD", kCounterAdd, &kCounterAddInfo, "add amount to the count"}};

}  // namespace example

extern "C" void rack_register_components(rack::ComponentRegistry& registry) {
  // The last field is its TiMS class name: rackd's own log lines then name its
  // addresses Counter(0/0), as the tools do from its description (not Class0x91(0/0)).
  registry.add({"Counter", example::kCounterClassId, "example: a counter built outside the tree",
                [] { return std::make_unique<example::Counter>(); }, &example::kCounterDataInfo,
                example::kCounterCommands, "Counter"});
}
