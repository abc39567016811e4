// TestCounter: a component class declared the way any class is (one folder, one
// rack_add_class in its CMakeLists.txt) and built as a plug-in outside the plug-in
// directory of the tree: the tests find it by name through `plugins:` and
// RACK_PLUGIN_PATH. Its data type and class command are declared here, in its folder,
// and nowhere else (tims/ and the tools' tables do not know it).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/core/data_component.h"

namespace rack::test_counter {

struct CounterData {
  int64_t count = 0;
  uint32_t peer = 0;  // the `peer` parameter: a raw TiMS address, which tools name by its class
  uint32_t spare = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(CounterData, count), RACK_FIELD(CounterData, peer), RACK_FIELD(CounterData, spare)};
  }
};
inline constexpr int8_t kReset = 21;
inline constexpr FieldValueNames kCounterNames[] = {{"peer", {}, true}};
inline constexpr DataTypeInfo kCounterType = data_type_info<CounterData>("CounterData", kCounterNames);
inline constexpr CommandInfo kCounterCommands[] = {{"RESET", kReset, nullptr, "the count to 0"}};

class TestCounter final : public DataComponent<CounterData> {
 public:
  TestCounter();

 protected:
  HookResult loop() override;  // RT
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  Parameter& step_;
  Parameter& peer_;
  std::atomic<int64_t> count_{0};
};

}  // namespace rack::test_counter
