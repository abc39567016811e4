// Declared inputs (DataComponentBase::declare_input), the command-to-data Handoff and
// the parameters' former names: the framework switches a declared source on and
// subscribes before on(), unsubscribes after off() (also after a failed ON),
// re-subscribes on the retry after ERROR, fails the consumer when a watched source is
// silent for silence_ms, and the host loader takes a parameter by its old name with a
// warning that names the file, line, key and new name.
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "rack/core/handoff.h"
#include "rack/core/host_config.h"
#include "monitor/monitor_types.h"
#include "rack/interfaces/demo.h"
#include "test_support.h"

namespace rack {
namespace {

using interfaces::MonitorData;
using test::generator_monitor_yaml;
using test::HostUnderTest;
using test::Stepping;
using test::Watchdog;
using tims::Address;
namespace msg = tims::msg;

uint64_t listeners(HostUnderTest& host, Address a) { return host.stats(a).listeners; }

// The DeclaredInputTest hosts are stepped (rack/core/stepper.h): waiting for a condition
// moves the virtual clock to the first instant it holds, within this much of it.
constexpr int64_t kLimit = 10 * rt::kNsPerSec;

TEST(DeclaredInputTest, SubscribedBeforeOnAndUnsubscribedAfterOff) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml(", source_period_ms: 20"), {}, false, Stepping::kStepped);
  const Address gen = host.address_of("gen");
  const Address mon = host.address_of("mon");
  EXPECT_EQ(host.status(gen), msg::kDisabled);
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  EXPECT_EQ(host.status(gen), msg::kEnabled) << "cascading ON of the declared source";
  EXPECT_EQ(listeners(host, gen), 1u) << "subscribed when ON was answered";
  MonitorData d{};
  wire::SampleHeader sh;
  ASSERT_TRUE(host.stepper().run_until([&] { return host.get_data(mon, sh, d) && d.received >= 3; }, kLimit));
  EXPECT_EQ(d.real_period_ns, 20 * rt::kNsPerMs) << "the period the source granted reaches on()";
  ASSERT_EQ(host.call(mon, msg::kOff).type, msg::kOk);
  EXPECT_EQ(listeners(host, gen), 0u) << "unsubscribed by the framework when OFF was answered";
}

TEST(DeclaredInputTest, ProducerErrorFailsAndTheRetryResubscribes) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml("", 1000), {}, false,
                     Stepping::kStepped);  // the reason is read before the retry
  const Address gen = host.address_of("gen");
  const Address mon = host.address_of("mon");
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  ASSERT_EQ(host.call(gen, msg::kOff).type, msg::kOk);
  ASSERT_TRUE(host.stepper().run_until([&] { return host.status(mon) == msg::kError; }, kLimit)) << host.log();
  EXPECT_NE(std::strstr(host.stats(mon).error_reason, "left ENABLED"), nullptr) << host.stats(mon).error_reason;
  // The retry (every retry_ms) switches the source on again and subscribes again.
  ASSERT_TRUE(host.stepper().run_until([&] { return host.status(mon) == msg::kEnabled; }, kLimit)) << host.log();
  EXPECT_EQ(host.status(gen), msg::kEnabled);
  EXPECT_TRUE(host.stepper().run_until([&] { return listeners(host, gen) == 1u; }, kLimit));
}

TEST(DeclaredInputTest, WatchedSourceSilentForSilenceMsFails) {
  Watchdog dog;
  // One sample a second asked of the source, silence after 200 ms: ERROR.
  HostUnderTest host(generator_monitor_yaml(", source_period_ms: 1500, silence_ms: 200", 60000), {}, false,
                     Stepping::kStepped);
  const Address mon = host.address_of("mon");
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  ASSERT_TRUE(host.stepper().run_until([&] { return host.status(mon) == msg::kError; }, 5 * rt::kNsPerSec))
      << host.log();
  const std::string reason = host.stats(mon).error_reason;
  EXPECT_NE(reason.find("sent nothing for"), std::string::npos) << reason;
  EXPECT_NE(reason.find("silence_ms 200"), std::string::npos) << reason;
}

TEST(DeclaredInputTest, OldParameterNamesLoadWithAWarning) {
  test::HostFileLoader loader;
  const std::string text = R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
  - name: mon
    class: Monitor
    data_task: {timeout_ms: 400}
    params:
      source: gen
      period_ms: 50
)";
  const LoadResult r = loader.load(text, "old.yaml");
  ASSERT_TRUE(r.errors.empty()) << r.errors.front().str();
  ASSERT_EQ(r.warnings.size(), 2u);
  const std::string all = test::text_of(r.warnings);
  EXPECT_NE(all.find("old.yaml:12:7: component 'mon': parameter 'period_ms' is now 'source_period_ms'"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("old.yaml:9:"), std::string::npos) << all;
  EXPECT_NE(all.find("component 'mon': data_task.timeout_ms is now the parameter silence_ms"), std::string::npos)
      << all;
  const Component* mon = test::component_named(r, "mon");
  ASSERT_NE(mon, nullptr);
  EXPECT_DOUBLE_EQ(mon->parameters().find("source_period_ms")->get_float(), 50.0);
  EXPECT_DOUBLE_EQ(mon->parameters().find("silence_ms")->get_float(), 400.0);

  // The old and the new name together: which one holds? Neither: an error.
  const std::string both = text + "      source_period_ms: 60\n";
  const LoadResult b = loader.load(both, "both.yaml");
  ASSERT_FALSE(b.errors.empty());
  EXPECT_NE(b.errors.front().str().find("'period_ms' and 'source_period_ms' are the same parameter"), std::string::npos)
      << b.errors.front().str();
}

// A former name works in GET_PARAM and SET_PARAM (rackctl set-param, rack-gui's
// parameter editor) as in the host file: the new parameter is read and set, and
// SET_PARAM's OK and the component's log name the new name.
TEST(DeclaredInputTest, OldParameterNamesWorkInSetParamWithAWarning) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml(""), {}, true, Stepping::kStepped);  // SET_PARAM's log line: at once
  const Address mon = host.address_of("mon");
  wire::ParamName name;
  wire::copy_text(name.name, "period_ms");
  const auto got = host.call_with(mon, msg::kGetParam, name);
  ASSERT_EQ(got.type, msg::kParam) << got.error_text();
  wire::ParamRecord record;
  ASSERT_EQ(got.body.size(), sizeof record);
  std::memcpy(&record, got.body.data(), sizeof record);
  EXPECT_STREQ(record.name, "source_period_ms") << "GET_PARAM by the old name answers with the new one";

  const auto set = host.set_param(mon, "period_ms", wire::ParamKind::kFloat, 0, 50.0);
  ASSERT_EQ(set.type, msg::kOk) << set.error_text();
  EXPECT_NE(set.error_text().find("parameter 'period_ms' is now 'source_period_ms' (the old name still works"),
            std::string::npos)
      << set.error_text();
  EXPECT_DOUBLE_EQ(host.executor().find("mon")->parameters().find("source_period_ms")->get_float(), 50.0);
  const auto plain = host.set_param(mon, "source_period_ms", wire::ParamKind::kFloat, 0, 60.0);
  EXPECT_EQ(plain.type, msg::kOk);
  EXPECT_TRUE(plain.body.empty()) << "no warning by the new name";
  host.executor().flush_log();
  EXPECT_NE(host.gdos_log().find("by the old name 'period_ms': the parameter is now 'source_period_ms'"),
            std::string::npos)
      << host.gdos_log();
  const auto unknown = host.set_param(mon, "no_such_ms", wire::ParamKind::kFloat, 0, 1.0);
  EXPECT_EQ(unknown.type, msg::kError);
  EXPECT_NE(unknown.error_text().find("unknown parameter 'no_such_ms'"), std::string::npos) << unknown.error_text();
}

// The timeouts that had names of their own (docs/parameters.md): a scan source's
// silence is silence_ms (Joystick), a device that sends nothing is device_timeout_ms
// (the drivers); the old names load with the warning. Every *_ms is a float, lease_ms too.
TEST(DeclaredInputTest, JoystickAndDriverTimeoutsLoadByTheirOldNames) {
  test::HostFileLoader loader;
  const std::string text = R"(system: 0
lcm: false
components:
  - name: stick
    class: Joystick
    data_task: {period_ms: 20, lease_ms: 2500.5}
    params: {obstacle_timeout_ms: 300}
  - name: hokuyo
    class: LadarHokuyo
    data_task: {period_ms: 25}
    params: {device: /dev/ttyACM0, timeout_ms: 700}
  - name: sick
    class: LadarSick
    instance: 1
    data_task: {period_ms: 25}
    params: {host: 192.168.0.1, timeout_ms: 600}
  - name: gps
    class: GpsNmea
    data_task: {period_ms: 100}
    params: {device: /dev/ttyUSB0, timeout_ms: 2500}
)";
  const LoadResult r = loader.load(text, "old.yaml");
  ASSERT_TRUE(r.errors.empty()) << r.errors.front().str();
  const std::string all = test::text_of(r.warnings);
  EXPECT_EQ(r.warnings.size(), 4u) << all;
  EXPECT_NE(all.find("component 'stick': parameter 'obstacle_timeout_ms' is now 'silence_ms'"), std::string::npos)
      << all;
  for (const char* c : {"hokuyo", "sick", "gps"}) {
    EXPECT_NE(all.find(std::string("component '") + c + "': parameter 'timeout_ms' is now 'device_timeout_ms'"),
              std::string::npos)
        << all;
  }
  const auto value = [&](const std::string& component, const char* param) {
    const Component* c = test::component_named(r, component);
    return c != nullptr ? c->parameters().find(param)->get_float() : -1.0;
  };
  EXPECT_DOUBLE_EQ(value("stick", "silence_ms"), 300.0);
  EXPECT_DOUBLE_EQ(value("hokuyo", "device_timeout_ms"), 700.0);
  EXPECT_DOUBLE_EQ(value("sick", "device_timeout_ms"), 600.0);
  EXPECT_DOUBLE_EQ(value("gps", "device_timeout_ms"), 2500.0);
  const Component* stick = test::component_named(r, "stick");
  ASSERT_NE(stick, nullptr);
  EXPECT_EQ(stick->settings().lease_ns, 2'500'500'000) << "lease_ms is a float";
}

TEST(HandoffTest, TheNewestRequestWinsAndCountsAddUp) {
  Handoff<int> latest;
  int v = 0;
  EXPECT_FALSE(latest.take(v));
  latest.post(1);
  latest.post(2);
  ASSERT_TRUE(latest.take(v));
  EXPECT_EQ(v, 2);
  EXPECT_FALSE(latest.take(v)) << "taken once";

  Handoff<uint32_t> count;
  count.post([](uint32_t& n) { ++n; });
  count.post([](uint32_t& n) { ++n; });
  uint32_t n = 0;
  ASSERT_TRUE(count.take(n));
  EXPECT_EQ(n, 2u);
  count.post([](uint32_t& k) { ++k; });
  count.clear();
  EXPECT_FALSE(count.take(n)) << "cleared";
  EXPECT_FALSE(count.pending());
}

}  // namespace
}  // namespace rack
