// The SDK end to end (issue 19, item 5): `cmake --install` of this build into a
// temporary prefix, examples/out_of_tree_class configured from that prefix's copy
// (share/rack/examples) with find_package(rack) and CMAKE_PREFIX_PATH=prefix (never
// the source tree), its plug-in loaded by the installed rackd from a host file, and
// the component driven by the installed rackctl: list, params, set-param, get-data,
// and its class commands.
//
// No tool is built with Counter (nor with any other class: they link the client
// library only): each learns the class from the description the component serves
// (GET_CLASS), exactly as it learns a built-in one. Checked for the plug-in, as a
// user of the installed tree meets it (issue 19 item 3):
//   - `rackd --list-classes host.yaml` lists it with its parameters' docs;
//   - rackctl: `list` and every reply name it Counter(0/0), and that address is
//     accepted; JSON data has its field names; `params` its docs; commands go by
//     name with field=value bodies;
//   - gdos selects and names its log records by that address;
//   - rack-gui (the dashboard's server) sends its data with field names under that
//     address, takes requests for that address, and sends its commands by name.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "ws_client.h"

namespace rack::test {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

const std::string kCmake = RACK_CMAKE;  // the cmake that configured this tree

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class SdkOutOfTreeTest : public ::testing::Test {
 protected:
  SdkOutOfTreeTest() : watchdog_(100s, "SdkOutOfTreeTest") {}

  RunResult ctl(std::vector<std::string> args) {
    args.insert(args.begin(), {(prefix() / "bin/rackctl").string(), "--lcm", bus_.url(), "--discover-ms", "3000"});
    return run(args, 30s);
  }
  fs::path prefix() const { return dir_.path() / "prefix"; }

  // The sample's count (CounterData.count: the first 8 bytes), nullopt when there is none.
  std::optional<int64_t> count() {
    const RunResult r = ctl({"get-data", "counter"});
    if (r.exit_code != 0) return std::nullopt;
    const auto j = parse_json(r.out);
    // The field by name: rackctl learns CounterData from the class's description.
    if (!j || j->get("data") == nullptr || j->at("data").get("count") == nullptr) return std::nullopt;
    return static_cast<int64_t>(j->at("data").at("count").number);
  }

  template <typename Pred>
  bool eventually(Pred pred) {
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    for (;;) {
      if (pred()) return true;
      if (std::chrono::steady_clock::now() >= deadline) return false;
      std::this_thread::sleep_for(50ms);
    }
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
};

TEST_F(SdkOutOfTreeTest, ExampleClassBuiltFromTheInstalledTreeRunsInRackd) {
  // 1. Install the programs, the SDK and rack-gui (its front end is optional: the
  // test reads what its server sends).
  for (const char* component : {"Runtime", "Development", "Gui"}) {
    const RunResult r = run(
        {kCmake, "--install", RACK_BINARY_DIR, "--prefix", prefix().string(), "--component", component}, 60s);
    ASSERT_EQ(r.exit_code, 0) << r.describe();
  }
  for (const char* file :
       {"bin/rackd", "bin/rackctl", "bin/rack-gui", "include/rack/core/component.h", "include/rack/client/host_file.h",
        "lib/cmake/rack/rackConfig.cmake", "lib/cmake/rack/rackConfigVersion.cmake", "lib/cmake/rack/RackPlugin.cmake",
        "share/rack/examples/out_of_tree_class/CMakeLists.txt", "share/rack/configs/demo.yaml",
        "lib/systemd/system/rackd@.service"}) {
    EXPECT_TRUE(fs::exists(prefix() / file)) << file;
  }
  EXPECT_TRUE(fs::is_directory(prefix() / "lib/rack/plugins"));
  // The installed rackd finds the installed plug-ins beside it and never searches the
  // build tree's plug-in directory (a later build there must not change what it loads).
  const RunResult listing = run({(prefix() / "bin/rackd").string(), "--list-classes"}, 30s);
  ASSERT_EQ(listing.exit_code, 0) << listing.describe();
  EXPECT_TRUE(contains(listing.out, (prefix() / "lib/rack/plugins").string())) << listing.out;
  EXPECT_FALSE(contains(listing.out, std::string(RACK_BINARY_DIR) + "/plugins")) << listing.out;
  EXPECT_TRUE(contains(listing.out, "MCL  (class")) << "the installed MCL plug-in: " << listing.out;

  // 2. Configure and build the example from the installed copy, against the prefix.
  const fs::path build = dir_.path() / "example";
  std::vector<std::string> configure{kCmake,
                                     "-S",
                                     (prefix() / "share/rack/examples/out_of_tree_class").string(),
                                     "-B",
                                     build.string(),
                                     "-DCMAKE_BUILD_TYPE=Release",
                                     "-DCMAKE_PREFIX_PATH=" + prefix().string(),
                                     "-DCMAKE_CXX_COMPILER=" RACK_CXX_COMPILER};
  if (const std::string launcher = RACK_CXX_COMPILER_LAUNCHER; !launcher.empty()) {
    configure.push_back("-DCMAKE_CXX_COMPILER_LAUNCHER=" + launcher);  // ccache: shared with the tree
  }
  RunResult r = run(configure, 60s);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  // find_package(rack) found the installed package, not the build or source tree.
  EXPECT_TRUE(contains(read_file(build / "CMakeCache.txt"), "rack_DIR:PATH=" + (prefix() / "lib/cmake/rack").string()))
      << r.describe();
  r = run({kCmake, "--build", build.string()}, 90s);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const fs::path plugin = build / "libcounter_class.so";
  ASSERT_TRUE(fs::exists(plugin)) << r.describe();

  // 3. The installed rackd loads it from a host file.
  const fs::path host = dir_.write("counter.yaml", "host: it-sdk\nsystem: 0\nheap_prefault_mib: 16\nplugins: [" +
                                                       plugin.string() +
                                                       "]\ncomponents:\n  - name: counter\n    class: Counter\n"
                                                       "    instance: 0\n    autostart: true\n"
                                                       "    data_task: {period_ms: 10}\n"
                                                       "    params: {step: 2, start: 1000}\n");
  const RunResult checked = run({(prefix() / "bin/rackd").string(), "--check", host.string()}, 30s);
  ASSERT_EQ(checked.exit_code, 0) << checked.describe();
  // --list-classes with the host file: the class of the library it names, with its
  // parameters, as the built-in classes are listed.
  const RunResult classes = run({(prefix() / "bin/rackd").string(), "--list-classes", host.string()}, 30s);
  ASSERT_EQ(classes.exit_code, 0) << classes.describe();
  EXPECT_TRUE(contains(classes.out, "Counter  (class Counter, data task: periodic)")) << classes.out;
  EXPECT_TRUE(contains(classes.out, "example: a counter built outside the tree")) << classes.out;
  EXPECT_TRUE(contains(classes.out, "added to the count every period")) << classes.out;
  Process rackd({(prefix() / "bin/rackd").string(), host.string(), "--lcm", bus_.url()}, dir_.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  // rackd's own lines name it by the TiMS class name it registered, as the tools do.
  EXPECT_TRUE(rackd.wait_for_stderr("Counter(0/0): ON", 15s)) << rackd.err();

  // 4. The installed rackctl drives it.
  r = ctl({"status", "counter", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto status = parse_json(r.out);
  ASSERT_TRUE(status.has_value()) << r.out;
  EXPECT_EQ(status->at("state").string, "ENABLED") << r.out;
  EXPECT_EQ(status->at("data_task").string, "periodic") << r.out;
  EXPECT_EQ(status->at("component").string, "Counter(0/0)") << r.out;

  // `list` names its class (from its description: rackctl links no class table).
  r = ctl({"list", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, R"j("address":"Counter(0/0)","name":"counter","class":"Counter","impl":"Counter")j"))
      << r.out;
  r = ctl({"list"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "Counter(0/0)")) << r.out;
  EXPECT_FALSE(contains(r.out, "Class0x")) << r.out;
  // Its address as an argument, and its data by field name.
  r = ctl({"get-data", "Counter(0/0)"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto sample = parse_json(r.out);
  ASSERT_TRUE(sample.has_value()) << r.out;
  EXPECT_EQ(sample->at("component").string, "Counter(0/0)") << r.out;
  ASSERT_NE(sample->get("data"), nullptr) << r.out;
  EXPECT_NE(sample->at("data").get("step"), nullptr) << r.out;

  r = ctl({"params", "counter"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "step") && contains(r.out, "int")) << r.describe();
  EXPECT_TRUE(contains(r.out, "start")) << r.describe();
  EXPECT_TRUE(contains(r.out, "added to the count every period")) << r.describe();

  // The count runs from start (1000) in steps of 2.
  ASSERT_TRUE(eventually([&] { return count().value_or(0) > 1000; }));
  EXPECT_EQ(count().value_or(1) % 2, 0);

  // RESET (21, no body) by its name: back to start.
  ASSERT_EQ(ctl({"set-param", "counter", "step", "0"}).exit_code, 0);
  r = ctl({"send", "counter", "RESET"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(eventually([&] { return count() == std::optional<int64_t>(1000); }));

  // ADD (22, CounterAdd{amount}) by its name, the body from its field.
  r = ctl({"send", "counter", "ADD", "amount=234"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(eventually([&] { return count() == std::optional<int64_t>(1234); }));
  // A malformed ADD (no body) is refused with the class's reason; rackd keeps running.
  r = ctl({"send", "counter", "22"});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.out + r.err, "ADD takes an 8-byte body")) << r.describe();

  // 5. The installed gdos (built with no class either) selects its log by the address
  // its class describes (Counter(0/0)) and prints that address.
  Process gdos({(prefix() / "bin/gdos").string(), "--lcm", bus_.url(), "--json", "--component", "Counter(0/0)",
                "--count", "1"},
               dir_.path(), "gdos");
  ASSERT_TRUE(gdos.wait_for_stderr("gdos: listening", 30s)) << gdos.err();
  ASSERT_EQ(ctl({"set-param", "counter", "gdosLevel", "detail"}).exit_code, 0);
  ASSERT_EQ(gdos.wait_exit(30s), std::optional<int>(0)) << gdos.err();
  const auto record = parse_json(gdos.out());
  ASSERT_TRUE(record.has_value()) << gdos.out();
  EXPECT_EQ(record->at("source").string, "Counter(0/0)") << gdos.out();
  EXPECT_EQ(record->at("name").string, "counter") << gdos.out();

  // 6. The installed rack-gui (built with no class either): the dashboard's data view
  // of the component, under its address by class name, and its commands by name.
  fs::create_directories(dir_.path() / "web");
  (void)dir_.write("web/index.html", "<html></html>");
  Process gui({(prefix() / "bin/rack-gui").string(), "--port", "0", "--lcm", bus_.url(), "--web",
               (dir_.path() / "web").string(), "--reports", "", "--poll-ms", "100"},
              dir_.path(), "rack-gui");
  ASSERT_TRUE(gui.wait_for_stderr("rack-gui: serving http://", 15s)) << gui.err();
  WsClient ws(served_port(gui.err()));
  nlohmann::json data;
  for (int i = 0; i < 100 && !data.is_object(); ++i) {
    const auto j = ws.read_type("data");
    ASSERT_TRUE(j.is_object()) << "no data message: " << gui.err();
    if (j.value("component", "") == "Counter(0/0)") data = j;
  }
  ASSERT_TRUE(data.is_object()) << gui.err();
  EXPECT_EQ(data["class"], "Counter") << data.dump();
  EXPECT_EQ(data["name"], "counter") << data.dump();
  ASSERT_TRUE(data["data"].is_object()) << data.dump();
  EXPECT_TRUE(data["data"]["count"].is_number()) << data.dump();
  EXPECT_TRUE(data["data"]["step"].is_number()) << data.dump();
  // The commands panel: the class's commands by name, ADD with its field.
  ws.send({{"op", "get_class"}, {"component", "Counter(0/0)"}, {"id", 1}});
  const auto cls = ws.read_type("class");
  ASSERT_TRUE(cls.is_object()) << gui.err();
  EXPECT_EQ(cls["component"], "Counter(0/0)") << cls.dump();
  EXPECT_TRUE(contains(cls["commands"].dump(), R"("name":"ADD")")) << cls.dump();
  const int64_t before = count().value_or(0);
  ws.send({{"op", "command"},
           {"component", "Counter(0/0)"},
           {"name", "ADD"},
           {"fields", {{"amount", "100000"}}},
           {"id", 2}});
  nlohmann::json added;
  for (int i = 0; i < 50 && !(added.is_object() && added.value("id", 0) == 2); ++i) added = ws.read_type("result");
  ASSERT_TRUE(added.is_object()) << gui.err();
  EXPECT_EQ(added["ok"], true) << added.dump();
  EXPECT_TRUE(contains(added["text"].get<std::string>(), "Counter(0/0): ADD")) << added.dump();
  EXPECT_GE(count().value_or(0), before + 100000);
  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();

  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(30s), std::optional<int>(0)) << rackd.err();
}

}  // namespace
}  // namespace rack::test
