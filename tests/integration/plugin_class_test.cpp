// Integration: component classes as plug-ins (issue 19 items 1 and 2). rackd links no
// heavy library; a plug-in class is found by its name (<Class>.rack-class) in the
// host file's plug-in directories, RACK_PLUGIN_PATH and the tree's plug-in
// directory, and loaded only when a host file names it; a missing or broken plug-in
// is an error that names the class and where rackd looked; --list-classes lists
// plug-in classes without loading them.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "process.h"
#include "rack/components/class_ids.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kTestPlugins = RACK_TEST_PLUGIN_DIR;  // TestCounter (tests/integration/plugin_class)
const std::string kRackctl = RACK_RACKCTL_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string maps_of(pid_t pid) { return read_file("/proc/" + std::to_string(pid) + "/maps"); }

class PluginClassTest : public ::testing::Test {
 protected:
  PluginClassTest() : watchdog_(60s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  std::string counter_host(const std::string& plugins_line) const {
    return "host: it-plugin\nsystem: 0\nheap_prefault_mib: 8\n" + plugins_line +
           "components:\n  - name: counter\n    class: TestCounter\n    instance: 0\n    data_task: {period_ms: 10}\n"
           "    params: {step: 3}\n";
  }

  Watchdog watchdog_;
  TempDir dir_;
};

TEST_F(PluginClassTest, RackdLinksNoHeavyLibrary) {
  // ldd lists every shared object the loader maps for rackd, transitively.
  const auto r = run({"/usr/bin/ldd", kRackd}, 30s);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(contains(r.out, "librack_core")) << "ldd output not as expected:\n" << r.out;
  for (const char* heavy : {"libmrpt", "libpcl_", "libopencv", "libvtk", "libQt"}) {
    EXPECT_FALSE(contains(r.out, heavy)) << "rackd links " << heavy << ":\n" << r.out;
  }
}

// Issue 19 item 4: the tools link the client library (protocol, session, discovery,
// key files), not the executor, its class table or a class: they learn every class
// from its description. ldd lists the shared objects the loader maps (transitively);
// nm the functions linked in statically (rack_components is a static library).
TEST_F(PluginClassTest, ToolsLinkTheClientLibraryNotTheExecutor) {
  for (const std::string& tool :
       {std::string(RACK_RACKCTL_PATH), std::string(RACK_GDOS_PATH), std::string(RACK_GUI_PATH)}) {
    const auto ldd = run({"/usr/bin/ldd", tool}, 30s);
    ASSERT_EQ(ldd.exit_code, 0) << ldd.describe();
    ASSERT_TRUE(contains(ldd.out, "librack_tims")) << "ldd output not as expected:\n" << ldd.out;
    for (const char* lib :
         {"librack_core.", "librack_interfaces.", "librack_devices.", "libmrpt", "libpcl_", "libopencv"}) {
      EXPECT_FALSE(contains(ldd.out, lib)) << tool << " links " << lib << ":\n" << ldd.out;
    }
    const auto nm = run({"/usr/bin/nm", "-C", "--defined-only", tool}, 30s);
    ASSERT_EQ(nm.exit_code, 0) << nm.describe();
    ASSERT_TRUE(contains(nm.out, "rack::client::Session")) << tool << ": nm output not as expected";
    for (const char* symbol : {"rack::Executor::", "rack::ComponentRegistry::", "rack::components::register_builtin",
                               "rack::interfaces::"}) {
      EXPECT_FALSE(contains(nm.out, symbol)) << tool << " has " << symbol << " linked in";
    }
  }
  // rackctl and gdos read host files with libyaml (rack/client/host_file.h), not
  // yaml-cpp (rack-gui reads occupancy maps' YAML through rack::maps).
  for (const std::string& tool : {std::string(RACK_RACKCTL_PATH), std::string(RACK_GDOS_PATH)}) {
    const auto ldd = run({"/usr/bin/ldd", tool}, 30s);
    EXPECT_FALSE(contains(ldd.out, "libyaml-cpp")) << tool << ":\n" << ldd.out;
  }
}

TEST_F(PluginClassTest, ListClassesNamesThePluginClassesWithoutLoadingThem) {
  const auto r = run({kRackd, "--list-classes"}, 30s);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "Generator  (class Generator, data task: ")) << r.out;
  for (const char* cls : {"MCL  (class MCL, plug-in ", "ChassisReplay  (class Chassis, plug-in ",
                          "LadarReplay  (class Ladar, plug-in ", "Scan3D  (class Scan3D, plug-in "}) {
    EXPECT_TRUE(contains(r.out, cls)) << cls << " missing:\n" << r.out;
  }
  // The test plug-in is not in the tree's plug-in directory; through RACK_PLUGIN_PATH it is.
  EXPECT_FALSE(contains(r.out, "TestCounter"));
  const auto with_path = run({"/usr/bin/env", "RACK_PLUGIN_PATH=" + kTestPlugins, kRackd, "--list-classes"}, 30s);
  ASSERT_EQ(with_path.exit_code, 0) << with_path.describe();
  EXPECT_TRUE(contains(with_path.out, "TestCounter  (class TestCounter, plug-in " + kTestPlugins + "/"))
      << with_path.out;
}

TEST_F(PluginClassTest, AHostFileWithoutHeavyClassesMapsNoHeavyLibrary) {
  LcmBus bus;
  const auto host = dir_.write(
      "demo.yaml",
      "host: it-light\nsystem: 0\nheap_prefault_mib: 8\ncomponents:\n"
      "  - name: gen\n    class: Generator\n    instance: 0\n    data_task: {period_ms: 10}\n");
  Process rackd({kRackd, host.string(), "--lcm", bus.url()}, dir_.path(), "light");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 20s)) << rackd.err();
  const std::string maps = maps_of(rackd.pid());
  for (const char* heavy : {"libmrpt", "libpcl_", "libopencv", "librack_plugin_"}) {
    EXPECT_FALSE(contains(maps, heavy)) << heavy << " is mapped";
  }
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), std::optional<int>(0)) << rackd.err();
}

// A host that loads no plug-in still knows the TiMS names of the tree's plug-in classes:
// a Monitor here may take its input from a Scan3D or a Camera on another host, by class
// name, without rackd mapping PCL or OpenCV (rack::class_ids::kTreeClasses).
TEST_F(PluginClassTest, AHostAddressesAPluginClassOnAnotherHostByNameWithoutLoadingIt) {
  std::string text = "host: it-remote-names\nsystem: 0\nlcm: false\ncomponents:\n";
  int instance = 0;
  for (const char* source : {"Scan3D(1/0)", "Camera(1/0)", "MCL(1/0)"}) {
    text += "  - name: mon" + std::to_string(instance) +
            "\n    class: Monitor\n    instance: " + std::to_string(instance) + "\n    params: {source: \"" + source +
            "\"}\n";
    ++instance;
  }
  const auto host = dir_.write("remote.yaml", text);
  const auto check = run({kRackd, "--check", host.string()}, 30s);
  EXPECT_EQ(check.exit_code, 0) << check.describe();
  EXPECT_FALSE(contains(check.out + check.err, "no component named")) << check.describe();
}

TEST_F(PluginClassTest, APluginClassIsFoundByNameThroughPluginsAndRuns) {
  LcmBus bus;
  const auto host = dir_.write("counter.yaml", counter_host("plugins: [" + kTestPlugins + "]\n"));
  const auto check = run({kRackd, "--check", host.string()}, 30s);
  EXPECT_EQ(check.exit_code, 0) << check.describe();
  Process rackd({kRackd, host.string(), "--lcm", bus.url()}, dir_.path(), "counter");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 20s)) << rackd.err();
  EXPECT_TRUE(contains(maps_of(rackd.pid()), kTestPlugins + "/librack_plugin_test_counter.so"));
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), std::optional<int>(0)) << rackd.err();
  EXPECT_TRUE(contains(rackd.out(), "counter")) << rackd.out();
}

TEST_F(PluginClassTest, APluginClassIsFoundThroughRackPluginPath) {
  const auto host = dir_.write("counter.yaml", counter_host(""));
  const auto without = run({kRackd, "--check", host.string()}, 30s);
  EXPECT_EQ(without.exit_code, 2) << without.describe();
  const auto with = run(
      {"/usr/bin/env", "RACK_PLUGIN_PATH=/nonexistent:" + kTestPlugins, kRackd, "--check", host.string()}, 30s);
  EXPECT_EQ(with.exit_code, 0) << with.describe();
}

TEST_F(PluginClassTest, AMissingPluginNamesTheClassAndWhereRackdLooked) {
  const auto host = dir_.write("missing.yaml",
                               "host: it-missing\nsystem: 0\ncomponents:\n"
                               "  - name: x\n    class: NoSuchClass\n    instance: 0\n");
  const auto r = run({"/usr/bin/env", "RACK_PLUGIN_PATH=" + dir_.path().string(), kRackd, "--check", host.string()},
                     30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "missing.yaml:5:")) << r.err;
  EXPECT_TRUE(contains(r.err, "'NoSuchClass'")) << r.err;
  EXPECT_TRUE(contains(r.err, "NoSuchClass.rack-class")) << r.err;
  EXPECT_TRUE(contains(r.err, dir_.path().string())) << "the directories searched: " << r.err;
}

TEST_F(PluginClassTest, ABrokenPluginIsAnErrorWithTheClassAndTheLibrary) {
  // A manifest whose library is not a shared object, and one that is malformed.
  dir_.write("Broken.rack-class", "class Broken\nlibrary libbroken.so\nsummary a text file, not ELF\n");
  dir_.write("libbroken.so", "not an ELF file\n");
  dir_.write("Garbled.rack-class", "class Garbled\nlibrary\n");
  for (const auto& [cls, expect] : std::vector<std::pair<std::string, std::string>>{
           {"Broken", dir_.path().string() + "/libbroken.so"}, {"Garbled", "Garbled.rack-class:2: 'library'"}}) {
    const auto host = dir_.write("broken.yaml", "host: it-broken\nsystem: 0\nplugins: [" + dir_.path().string() +
                                                    "]\ncomponents:\n  - name: x\n    class: " + cls +
                                                    "\n    instance: 0\n");
    const auto r = run({kRackd, "--check", host.string()}, 30s);
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    EXPECT_TRUE(contains(r.err, "class '" + cls + "'")) << r.err;
    EXPECT_TRUE(contains(r.err, expect)) << r.err;
  }
}

// A stale plug-in (built against other RACK-RT headers) is refused before any of its
// code runs (rack/core/plugin_abi.h), with the file, the ABI it was built for and the
// one rackd expects; an unstamped one (built before stamps) alike. As with any other
// bad plug-in the host file is refused (exit 2, its errors counted), whether the file
// names the library or a manifest leads to it.
TEST_F(PluginClassTest, AStalePluginIsRefusedBeforeItsCodeRuns) {
  const auto listing = run({kRackd, "--list-classes"}, 30s);
  ASSERT_EQ(listing.exit_code, 0) << listing.describe();
  const std::string marker = "plug-ins must be built for plug-in ABI ";
  const auto at = listing.out.find(marker);
  ASSERT_NE(at, std::string::npos) << listing.out;
  const std::string expected = listing.out.substr(at + marker.size(),
                                                  listing.out.find(" (rack/", at) - at - marker.size());
  ASSERT_EQ(expected.size(), std::string("0123456789abcdef (RACK-RT 0.1.0)").size()) << expected;

  const std::string foreign = RACK_FOREIGN_PLUGIN_PATH;
  const std::string unstamped = RACK_UNSTAMPED_PLUGIN_PATH;
  for (const auto& [lib, built_for] : std::vector<std::pair<std::string, std::string>>{
           {foreign, "was built for plug-in ABI 0123456789abcdef (RACK-RT 0.0.1)"},
           {unstamped, "carries no ABI stamp"}}) {
    // The library named in `plugins:`, beside a good component.
    const auto host = dir_.write("stale.yaml", "host: it-stale\nsystem: 0\nplugins: [" + lib +
                                                   "]\ncomponents:\n  - name: gen\n    class: Generator\n"
                                                   "    instance: 0\n    data_task: {period_ms: 10}\n");
    for (const bool check : {true, false}) {
      std::vector<std::string> args{kRackd, host.string()};
      if (check) args.insert(args.begin() + 1, "--check");
      const auto r = run(args, 30s);
      EXPECT_EQ(r.exit_code, 2) << r.describe();
      EXPECT_TRUE(contains(r.err, host.string() + ":3:")) << "the plugins: entry: " << r.err;
      EXPECT_TRUE(contains(r.err, "plug-in " + lib + " " + built_for)) << r.err;
      EXPECT_TRUE(contains(r.err, "this rackd expects ABI " + expected)) << r.err;
      EXPECT_TRUE(contains(r.err, "1 error(s) in " + host.string())) << r.err;
      EXPECT_FALSE(contains(r.err, "its code ran")) << "dlopen ran the plug-in's constructor: " << r.err;
    }
    // Found by class name through a manifest: the error names the class too.
    dir_.write("StaleClass.rack-class", "class StaleClass\nlibrary " + lib + "\n");
    const auto by_name = dir_.write("by_name.yaml", "host: it-stale\nsystem: 0\nplugins: [" + dir_.path().string() +
                                                        "]\ncomponents:\n  - name: old\n    class: StaleClass\n"
                                                        "    instance: 0\n");
    const auto r = run({kRackd, "--check", by_name.string()}, 30s);
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    EXPECT_TRUE(contains(r.err, "class 'StaleClass'")) << r.err;
    EXPECT_TRUE(contains(r.err, built_for)) << r.err;
    EXPECT_TRUE(contains(r.err, "this rackd expects ABI " + expected)) << r.err;
    EXPECT_FALSE(contains(r.err, "its code ran")) << r.err;
  }
  // The in-tree plug-in carries rackd's stamp (readelf -n shows the note).
  const auto notes = run({"/usr/bin/readelf", "-n", kTestPlugins + "/librack_plugin_test_counter.so"}, 30s);
  ASSERT_EQ(notes.exit_code, 0) << notes.describe();
  EXPECT_TRUE(contains(notes.out, "RACK")) << notes.out;
}

// rackctl watch names an address field by the class of the component it names
// (GET_CLASS), asked without holding up the samples: when that component does not
// answer (a Probe whose command task is busy in a slow on()), every sample still comes
// in order (the old watch waited for the reply inside the stream, and the 16-slot data
// mailbox dropped what arrived meanwhile), the field prints as Class0x42(0/0), and the
// watch says once that the class went undescribed.
TEST_F(PluginClassTest, WatchDoesNotWaitForAComponentThatDoesNotDescribeItsClass) {
  LcmBus bus;
  const uint32_t peer = uint32_t{rack::class_ids::kProbe} << 16;  // Probe(0/0)
  const auto host = dir_.write("peer.yaml", "host: it-peer\nsystem: 0\nheap_prefault_mib: 8\nplugins: [" +
                                                kTestPlugins +
                                                "]\ncomponents:\n  - name: counter\n    class: TestCounter\n"
                                                "    instance: 0\n    autostart: true\n"
                                                "    data_task: {period_ms: 20}\n    params: {peer: " +
                                                std::to_string(peer) +
                                                "}\n  - name: stuck\n    class: Probe\n    instance: 0\n"
                                                "    data_task: {period_ms: 100}\n    params: {on_delay_ms: 6000}\n");
  Process rackd({kRackd, host.string(), "--lcm", bus.url()}, dir_.path(), "counter");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 20s)) << rackd.err();
  // ON keeps the probe's command task in on() for 6 s: wait until it stops answering.
  Process on({kRackctl, "--lcm", bus.url(), "--timeout", "10000", "on", "stuck"}, dir_.path(), "on");
  bool busy = false;
  for (int i = 0; i < 50 && !busy; ++i) {
    busy = run({kRackctl, "--lcm", bus.url(), "--timeout", "200", "--retries", "0", "status", "stuck"}, 20s)
               .exit_code == 3;
  }
  ASSERT_TRUE(busy) << "the probe kept answering";
  // 100 samples at 50 Hz (2 s); the probe's GET_CLASS gives up after 1 s, meanwhile
  // 50 samples arrive: more than the data mailbox holds.
  const auto r = run(
      {kRackctl, "--lcm", bus.url(), "--timeout", "1000", "--retries", "0", "watch", "counter", "--count", "100"}, 30s);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  std::vector<long long> sequences;
  std::size_t named = 0;
  std::size_t from = 0;
  while (from < r.out.size()) {
    const auto end = r.out.find('\n', from);
    const std::string line = r.out.substr(from, end == std::string::npos ? std::string::npos : end - from);
    from = end == std::string::npos ? r.out.size() : end + 1;
    const auto at = line.find("\"sequence\":");
    ASSERT_NE(at, std::string::npos) << line;
    sequences.push_back(std::stoll(line.substr(at + 11)));
    if (contains(line, R"x("names":{"peer":"Class0x42(0/0)"})x")) ++named;
  }
  ASSERT_EQ(sequences.size(), 100u) << r.out;
  for (std::size_t i = 1; i < sequences.size(); ++i) {
    EXPECT_EQ(sequences[i], sequences[i - 1] + 1) << "a sample lost after sample " << i << ":\n" << r.out;
  }
  EXPECT_EQ(named, 100u) << r.out;
  EXPECT_TRUE(contains(r.err, "no reply to GET_CLASS within 1000 ms x 1 attempt(s)")) << r.err;
  EXPECT_EQ(on.wait_exit(20s), std::optional<int>(0)) << on.err();
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), std::optional<int>(0)) << rackd.err();
}

// Plug-in classes offline (issue 25): `rackd --list-classes --json HOSTFILE` searches
// the file's plugins: directories and describes the plug-in classes it names in full
// (class id, parameters), so `rackctl graph` gives a plug-in component its address
// (TestCounter(0/0), not a guess with '?') without a running rackd.
TEST_F(PluginClassTest, ListClassesWithAHostFileDescribesItsPluginClasses) {
  const auto host = dir_.write("counter.yaml", counter_host("plugins: [" + kTestPlugins + "]\n"));
  const auto alone = run({kRackd, "--list-classes", "--json"}, 30s);
  ASSERT_EQ(alone.exit_code, 0) << alone.describe();
  EXPECT_FALSE(contains(alone.out, "TestCounter")) << "not in the tree's plug-in directory";
  const auto listed = run({kRackd, "--list-classes", "--json", host.string()}, 30s);
  ASSERT_EQ(listed.exit_code, 0) << listed.describe();
  EXPECT_TRUE(contains(listed.out, R"({"impl":"TestCounter","class":"TestCounter","summary":"test: counts by 'step' )"))
      << listed.out;
  EXPECT_TRUE(contains(listed.out, R"("class_id":145,"plugin":true,"parameters":[)")) << listed.out;
  EXPECT_TRUE(contains(listed.out, R"({"name":"step","kind":"int","unit":"","min":1,"max":1000,"default":"1")"))
      << listed.out;
  EXPECT_EQ(listed.out.find(R"("impl":"TestCounter")"), listed.out.rfind(R"("impl":"TestCounter")"))
      << "listed once (described, not again by its manifest): " << listed.out;
  // A file with errors still lists what loads, and says what is wrong on stderr.
  const auto bad = dir_.write("bad.yaml", counter_host("plugins: [" + kTestPlugins + "]\n") + "bogus: 1\n");
  const auto with_bad = run({kRackd, "--list-classes", "--json", bad.string()}, 30s);
  ASSERT_EQ(with_bad.exit_code, 0) << with_bad.describe();
  EXPECT_TRUE(contains(with_bad.out, R"("class_id":145,"plugin":true)")) << with_bad.out;
  EXPECT_TRUE(contains(with_bad.err, "rackd: --list-classes: " + bad.string() + ":")) << with_bad.err;

  const auto graph = run({kRackctl, "graph", "--format", "json", "--rackd", kRackd, host.string()}, 30s);
  ASSERT_EQ(graph.exit_code, 0) << graph.describe();
  EXPECT_TRUE(contains(graph.out, R"x("name":"counter","impl":"TestCounter","address":"TestCounter(0/0)")x"))
      << graph.out;
}

}  // namespace
}  // namespace rack::test
