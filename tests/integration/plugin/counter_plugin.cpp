// A component class that no tool is built with (class id 0x91, in a plug-in): it
// publishes a sample with named fields, takes a command with a body, and declares
// documented parameters with units. The class-description test drives it with
// rackctl and rack-gui, which learn all of it from GET_CLASS.
#include <array>
#include <atomic>
#include <cstring>
#include <memory>

#include "rack/core/class_types.h"
#include "rack/core/data_component.h"
#include "rack/core/registry.h"

namespace {

struct CounterData {
  int64_t count = 0;
  double rate = 0.0;  // counts per second
  char label[16] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(CounterData, count), RACK_FIELD(CounterData, rate), RACK_FIELD(CounterData, label)};
  }
};

struct CounterReset {
  int64_t start = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(CounterReset, start)}; }
};

constexpr int8_t kCounterReset = 21;

const rack::FieldUnit kCounterUnits[] = {{"rate", "1/s"}};  // tools show it (rackctl classes)
const rack::DataTypeInfo kCounterDataInfo = rack::data_type_info<CounterData>("CounterData", {}, kCounterUnits);
const rack::DataTypeInfo kCounterResetInfo = rack::data_type_info<CounterReset>("CounterReset");
const std::array<rack::CommandInfo, 1> kCounterCommands = {
    rack::CommandInfo{"RESET", kCounterReset, &kCounterResetInfo, "count on from `start`"}};

class Counter final : public rack::DataComponent<CounterData> {
 public:
  Counter()
      : DataComponent(rack::DataTaskMode::kPeriodic),
        step_(declare_int("step", 1, {.doc = "added to the count every period", .min = 0, .max = 1000})),
        label_(declare_string("label", "counter", {.doc = "copied into every sample"})),
        rate_scale_(declare_float("rate_scale", 1.0,
                                  {.doc = "multiplies the rate it reports", .min = 0.0, .max = 10.0, .unit = "1/s"})) {}

 protected:
  rack::HookResult loop() override {
    CounterData d;
    d.count = count_.fetch_add(step_.get_int(), std::memory_order_relaxed) + step_.get_int();
    d.rate = rate_scale_.get_float() * 1e9 / static_cast<double>(settings().period_ns);
    label_.copy_string(d.label, sizeof d.label);
    publish(d, rack::rt::host_time_ns());
    return rack::HookResult::kOk;
  }
  rack::CommandResult command(const rack::tims::MessageHeader& request, std::span<const std::byte> body) override {
    if (request.type != kCounterReset) return rack::CommandResult::kUnknown;
    CounterReset r;
    if (!rack::wire::read_payload(body, rack::tims::body_is_native(request), r)) {
      reject_malformed(request, "RESET takes an 8-byte body (start)");
      return rack::CommandResult::kHandled;
    }
    // Relaxed: the count is the data task's; a reset only needs to land.
    count_.store(r.start, std::memory_order_relaxed);
    reply(request, rack::tims::msg::kOk);
    return rack::CommandResult::kHandled;
  }

 private:
  rack::Parameter& step_;
  rack::Parameter& label_;
  rack::Parameter& rate_scale_;
  std::atomic<int64_t> count_{0};
};

}  // namespace

extern "C" void rack_register_components(rack::ComponentRegistry& registry) {
  rack::ComponentClass cls{"Counter", 0x91, "test: a plug-in class that counts, with RESET start=N",
                           [] { return std::make_unique<Counter>(); }};
  cls.data = &kCounterDataInfo;
  cls.commands = kCounterCommands;
  registry.add(std::move(cls));
}
