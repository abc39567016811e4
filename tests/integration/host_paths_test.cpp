// Integration: paths in a host file are relative to the host file's folder, not to
// rackd's working directory (issue 21 item 3). rackd runs from another folder (/tmp)
// with a host file that names a map and a plug-in directory relatively; rackd
// --check fails on a named file that does not exist, with file:line:col and the
// absolute path it tried; the shipped configs check from any folder.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;
const std::string kTestPlugins = RACK_TEST_PLUGIN_DIR;  // TestCounter.rack-class

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// `args` run with /tmp as the working directory (coreutils env -C): nothing the host
// file names is there.
std::vector<std::string> from_tmp(std::vector<std::string> args) {
  args.insert(args.begin(), {"/usr/bin/env", "-C", "/tmp"});
  return args;
}

class HostPathsTest : public ::testing::Test {
 protected:
  HostPathsTest() : watchdog_(60s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {
    // <dir>/robot/host.yaml beside its maps/ and plugins/ (a link to the test plug-ins).
    robot_ = dir_.path() / "robot";
    fs::create_directories(robot_ / "maps");
    fs::copy_file(kConfigs + "/maps/office.yaml", robot_ / "maps/office.yaml");
    fs::copy_file(kConfigs + "/maps/office.pgm", robot_ / "maps/office.pgm");
    fs::create_directory_symlink(kTestPlugins, robot_ / "plugins");
  }

  std::string host_file(const std::string& name, const std::string& map) {
    const std::string text =
        "host: it-paths\nsystem: 0\nheap_prefault_mib: 8\n"
        "plugins: [plugins]\n"
        "components:\n"
        "  - name: chassis\n    class: ChassisSim\n    instance: 0\n"
        "    data_task: {period_ms: 20}\n"
        "    params:\n      map: " +
        map +
        "\n      initial_x: 4.0\n      initial_y: 7.2\n"
        "  - name: counter\n    class: TestCounter\n    instance: 0\n    data_task: {period_ms: 10}\n";
    const fs::path path = robot_ / name;
    write_text(path, text);
    return path.string();
  }
  static void write_text(const fs::path& path, const std::string& text) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr) << path;
    std::fputs(text.c_str(), f);
    std::fclose(f);
  }

  Watchdog watchdog_;
  TempDir dir_;
  fs::path robot_;
};

TEST_F(HostPathsTest, RackdRunsFromAnotherFolderWithAMapAndAPluginDirRelativeToTheHostFile) {
  const std::string host = host_file("host.yaml", "maps/office.yaml");
  const RunResult check = run(from_tmp({kRackd, "--check", host}), 30s);
  EXPECT_EQ(check.exit_code, 0) << check.describe();

  LcmBus bus;
  Process rackd(from_tmp({kRackd, host, "--lcm", bus.url()}), dir_.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  const auto ctl = [&](std::vector<std::string> args) {
    args.insert(args.begin(), {kRackctl, "--lcm", bus.url(), "--discover-ms", "3000"});
    return run(from_tmp(std::move(args)), 30s);
  };
  // The parameter holds the path made absolute: what rack-gui and rackctl see.
  const std::string absolute_map = (robot_ / "maps/office.yaml").string();
  const RunResult params = ctl({"params", "chassis"});
  ASSERT_EQ(params.exit_code, 0) << params.describe();
  EXPECT_TRUE(contains(params.out, absolute_map)) << params.out;
  // The map loaded (init() ran at start) and the plug-in class runs: both switch on.
  for (const char* name : {"chassis", "counter"}) {
    const RunResult on = ctl({"on", name});
    EXPECT_EQ(on.exit_code, 0) << name << ": " << on.describe() << rackd.err();
  }
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), std::optional<int>(0)) << rackd.err();
}

TEST_F(HostPathsTest, CheckFailsOnAMissingFileWithItsLineAndAbsolutePath) {
  const std::string host = host_file("missing.yaml", "maps/nowhere.yaml");
  const RunResult r = run(from_tmp({kRackd, "--check", host}), 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  // file:line:col of the map's value (line 11, after "      map: "), the absolute path tried.
  EXPECT_TRUE(contains(r.err, host + ":11:12: component 'chassis': parameter 'map': " +
                                  (robot_ / "maps/nowhere.yaml").string() + ": No such file or directory"))
      << r.err;
  EXPECT_TRUE(contains(r.err, "'maps/nowhere.yaml' is relative to the host file's folder, " + robot_.string()))
      << r.err;
  // A missing plug-in directory too.
  write_text(robot_ / "noplugins.yaml", "host: p\nsystem: 0\nplugins: [gone]\ncomponents: []\n");
  const RunResult p = run(from_tmp({kRackd, "--check", (robot_ / "noplugins.yaml").string()}), 30s);
  EXPECT_EQ(p.exit_code, 2) << p.describe();
  EXPECT_TRUE(contains(p.err, ":3:11: plug-in " + (robot_ / "gone").string() + ": No such file or directory")) << p.err;
}

TEST_F(HostPathsTest, TheShippedConfigsCheckFromAnyFolder) {
  for (const char* config :
       {"sim_nav.yaml", "sim_mcl.yaml", "replay_carmen.yaml", "replay_carmen_mcl.yaml", "sim_scan3d.yaml"}) {
    const RunResult r = run(from_tmp({kRackd, "--check", kConfigs + "/" + config}), 30s);
    EXPECT_EQ(r.exit_code, 0) << config << ": " << r.describe();
  }
}

}  // namespace
}  // namespace rack::test
