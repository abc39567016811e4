// The test programs that link the built-in classes run as rackd does: with the classes
// registered, so that TiMS knows their names (Chassis(0/1), not Class0x10(0/1)) before
// any test runs. TiMS learns a class's name only when a registry adds the class
// (tims/ knows no component class, and no program links a table of the classes);
// tests that print, parse or filter addresses by class name depend on it.
#include <gtest/gtest.h>

#include "rack/components/builtin.h"
#include "rack/core/registry.h"

namespace {

class BuiltinClassNames final : public ::testing::Environment {
 public:
  void SetUp() override { rack::components::register_builtin(registry_); }

 private:
  rack::ComponentRegistry registry_;
};

// Before main(): gtest_main's RUN_ALL_TESTS() sets it up before the first test.
[[maybe_unused]] ::testing::Environment* const kBuiltinClassNames = ::testing::AddGlobalTestEnvironment(
    new BuiltinClassNames);

}  // namespace
