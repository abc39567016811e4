// End to end: rack-gui's configuration tool (issue 25) in headless Chromium (Debian's
// chromium, driven by playwright-core): rack-gui serves a copy of configs/two_robots/
// (--config), the page draws the deployment graph (and, live, robot1_aux.yaml's
// running rackd measured, the other hosts stale; and from discovery alone, without
// host files, its tasks' priorities and period as they run), an invalid priority set in the
// editor's form is shown at its line by rackd --check, the fixed file is saved, and
// rackd --check accepts the file on disk, with only that value changed (comments and
// layout kept). The browser part is tools/gui/web/e2e/config_e2e.mjs; screenshots
// (config-*.png) go to the build directory (tests/integration/gui_e2e_artifacts/).
//
// Skips (with the reason) only when node, chromium or graphviz's dot is not
// installed; a missing npm install or front-end build is a failure.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

TEST(GuiConfigE2eTest, EditsAHostFileWithTheValidatorInTheLoop) {
  Watchdog watchdog(150s, "GuiConfigE2eTest");
  const std::string web = RACK_GUI_WEB_DIR;
  const std::string artifacts = RACK_GUI_ARTIFACTS_DIR;
  const BrowserTools browser = find_browser_tools();
  if (!browser.missing.empty()) GTEST_SKIP() << browser.missing;
  if (!find_program("dot"))
    GTEST_SKIP() << "graphviz's dot is not installed (apt-get install graphviz); scripts/setup.sh installs it";
  ASSERT_TRUE(std::filesystem::exists(web + "/node_modules/playwright-core"))
      << "playwright-core is missing: run scripts/setup.sh (npm ci in " << web << ")";
  ASSERT_TRUE(std::filesystem::exists(web + "/dist/index.html"))
      << "the front end is not built: run scripts/setup.sh (npm run build in " << web << ")";

  TempDir dir;
  const auto fleet = dir.path() / "two_robots";
  std::filesystem::create_directories(fleet);
  for (const auto& e : std::filesystem::directory_iterator(std::string(RACK_CONFIGS_DIR) + "/two_robots")) {
    std::filesystem::copy_file(e.path(), fleet / e.path().filename());
  }
  const auto edited = fleet / "robot1_aux.yaml";
  const std::string before = read_file(edited);
  LcmBus bus;
  // robot1_aux.yaml's rackd on rack-gui's network (the other hosts do not run): the
  // live view shows its scanner measured and the other hosts stale.
  const auto run_copy = dir.write("run_aux.yaml", before);
  Process rackd({RACK_RACKD_PATH, run_copy.string(), "--lcm", bus.url()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  Process gui({RACK_GUI_PATH, "--port", "0", "--lcm", bus.url(), "--web", web + "/dist", "--reports", "", "--config",
               fleet.string(), "--rackd", RACK_RACKD_PATH},
              dir.path(), "rack-gui");
  const std::string url = served_url(gui);
  ASSERT_FALSE(url.empty()) << gui.err();

  std::filesystem::create_directories(artifacts);
  const RunResult r = run({browser.node, web + "/e2e/config_e2e.mjs", "--url", url, "--chromium", browser.chromium,
                           "--shots", artifacts, "--file", "robot1_aux.yaml", "--live", "1", "--padding", "900"},
                          120s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe() << "\nrack-gui:\n" << gui.err();
  for (const char* shot :
       {"config-graph.png", "config-live.png", "config-running.png", "config-error.png", "config-saved.png"}) {
    EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(artifacts) / shot)) << shot;
  }
  // The saved file: valid for rackd, the priority changed, everything else as it was.
  const RunResult check = run({RACK_RACKD_PATH, "--check", edited.string()}, 30s);
  EXPECT_EQ(check.exit_code, 0) << check.describe();
  const std::string after = read_file(edited);
  std::string expected = before;
  const auto p = expected.find("data_task: {priority: 60,");
  ASSERT_NE(p, std::string::npos) << before;
  expected.replace(p, std::string("data_task: {priority: 60,").size(), "data_task: {priority: 65,");
  const auto a = expected.find("params: {amplitude: 1.0, frequency_hz: 0.5}");
  ASSERT_NE(a, std::string::npos) << before;
  expected.replace(a, std::string("params: {amplitude: 1.0,").size(), "params: {amplitude: 1.5,");
  // The one-line params edited in place; then 900 comment lines (above one WebSocket
  // message: sent in parts).
  for (int i = 0; i < 900; ++i) {
    expected += "# padding " + std::to_string(i) +
                ": a comment line that makes this host file larger than one WebSocket message\n";
  }
  EXPECT_GT(after.size(), 64u * 1024u);
  EXPECT_EQ(after, expected);
  // Nothing but the host files is left in the directory (the check's temporary files).
  std::size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(fleet)) {
    ++files;
    EXPECT_NE(e.path().filename().string()[0], '.') << e.path();
  }
  EXPECT_EQ(files, 4u);
  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(30s), std::optional<int>(0)) << rackd.err();
}

}  // namespace
}  // namespace rack::test
