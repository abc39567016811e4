// Classes describe themselves (issue 19, item 3): a class that no tool is built with
// (the Counter plug-in, class id 0x91) is printed, addressed, commanded and
// documented by the real rackctl exactly like a built-in one, from the description
// its component serves (GET_CLASS).
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "mini_json.h"
#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kCounterPlugin = RACK_COUNTER_PLUGIN_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class ClassDescriptionTest : public ::testing::Test {
 protected:
  ClassDescriptionTest()
      : watchdog_(60s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  RunResult ctl(std::vector<std::string> args, const std::string& discover_ms = "3000") {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url(), "--discover-ms", discover_ms});
    return run(args, 30s);
  }

  std::unique_ptr<Process> start_counter() {
    const auto file = dir_.write("counter.yaml", "host: it-describe\nsystem: 2\nheap_prefault_mib: 16\nplugins: [" +
                                                     kCounterPlugin +
                                                     "]\ncomponents:\n"
                                                     "  - name: counter\n    class: Counter\n    instance: 0\n"
                                                     "    autostart: true\n    data_task: {period_ms: 20}\n"
                                                     "    params: {step: 2, label: hello}\n");
    auto p = std::make_unique<Process>(std::vector<std::string>{kRackd, file.string(), "--lcm", bus_.url()},
                                       dir_.path(), "rackd");
    if (!p->wait_for_stderr("rackd: running", 30s)) {
      ADD_FAILURE() << "rackd did not start:\n" << p->err();
      return nullptr;
    }
    return p;
  }

  Watchdog watchdog_;
  LcmBus bus_;
  TempDir dir_;
};

TEST_F(ClassDescriptionTest, RackctlDrivesAPluginClassByItsDescription) {
  auto rackd = start_counter();
  ASSERT_TRUE(rackd);

  // Data as JSON with the class's field names, the address with its class name.
  RunResult r = ctl({"get-data", "counter"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  auto j = parse_json(r.out);
  ASSERT_TRUE(j) << r.out;
  EXPECT_EQ(j->at("component").string, "Counter(2/0)") << r.out;
  ASSERT_TRUE(j->at("data").is_object()) << "no field names: " << r.out;
  EXPECT_EQ(j->at("data").at("label").string, "hello") << r.out;
  EXPECT_DOUBLE_EQ(j->at("data").at("rate").number, 50.0) << r.out;
  EXPECT_GT(j->at("data").at("count").number, 0.0) << r.out;

  // Its command by name with a field=value body, at an address given by class name.
  r = ctl({"send", "Counter(2/0)", "RESET", "start=1000000"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.err, "RESET {\"start\": 1000000}")) << r.err;
  r = ctl({"get-data", "Counter(2/0)"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  j = parse_json(r.out);
  ASSERT_TRUE(j) << r.out;
  EXPECT_GE(j->at("data").at("count").number, 1000000.0) << r.out;
  // A field the command's body does not have, a command the class does not have.
  r = ctl({"send", "counter", "RESET", "begin=1"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "CounterReset has no field 'begin' (fields: start)")) << r.err;
  r = ctl({"send", "counter", "FREEZE"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "class Counter has no command 'FREEZE' (known: RESET)")) << r.err;
  // An address of a class name no running component describes.
  r = ctl({"status", "Nothing(2/0)"}, "500");
  EXPECT_EQ(r.exit_code, 3) << r.describe();

  // Parameters with their docs and units.
  r = ctl({"params", "Counter(2/0)"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "added to the count every period [0..1000, default 1]")) << r.out;
  EXPECT_TRUE(contains(r.out, "rate_scale           float  1 1/s")) << r.out;
  EXPECT_TRUE(contains(r.out, "multiplies the rate it reports [0..10 1/s, default 1]")) << r.out;
  r = ctl({"params", "counter", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  j = parse_json(r.out);
  ASSERT_TRUE(j && j->type == Json::Type::kArray) << r.out;
  bool found = false;
  for (const Json& p : j->array) {
    if (p.at("name").string != "rate_scale") continue;
    found = true;
    EXPECT_EQ(p.at("spec").at("unit").string, "1/s") << r.out;
    EXPECT_EQ(p.at("spec").at("max").number, 10.0) << r.out;
  }
  EXPECT_TRUE(found) << r.out;

  // The class listing, and list's class column.
  r = ctl({"classes", "it-describe"}, "1000");
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "Counter(Counter) class 0x91 on it-describe (system 2)")) << r.out;
  EXPECT_TRUE(contains(r.out, "data      CounterData (32 bytes): count:i64 rate:f64 label:char[16]")) << r.out;
  EXPECT_TRUE(contains(r.out, "command   RESET 21 CounterReset (8 bytes): start:i64 - count on from `start`")) << r.out;
  r = ctl({"list"}, "1000");
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "Counter(2/0)")) << r.out;
  EXPECT_TRUE(contains(r.out, "Counter(Counter)")) << r.out;

  // watch prints the fields too.
  r = ctl({"watch", "counter", "--count", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "\"label\": \"hello\"")) << r.out;
}

}  // namespace
}  // namespace rack::test
