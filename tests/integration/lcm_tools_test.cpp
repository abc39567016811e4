// LCM's own tools on TiMS traffic: lcm-logger records a session (an operator's
// commands to a component, the host's announcements and its replies), and
// lcm-logplayer plays the recording back into a freshly started host, whose component
// receives the recorded commands and ends up configured as in the session.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string find_tool(const std::string& name) {
  for (const char* dir : {"/usr/bin/", "/usr/local/bin/", "/bin/"}) {
    const std::string p = dir + name;
    if (access(p.c_str(), X_OK) == 0) return p;
  }
  return "";
}

constexpr const char* kHost = R"(host: logged
system: 0
host_id: 0
heap_prefault_mib: 0
components:
  - name: generator
    class: Generator
    instance: 0
    command_task: {priority: 30}
    data_task: {priority: 60, period_ms: 10}
    params: {amplitude: 2.0, frequency_hz: 0.5}
)";

class LcmToolsTest : public ::testing::Test {
 protected:
  LcmToolsTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  std::unique_ptr<Process> start_rackd(const std::string& tag) {
    auto p = std::make_unique<Process>(std::vector<std::string>{kRackd, host_file_.string(), "--lcm", bus_.url()},
                                       dir_.path(), tag);
    if (!p->wait_for_stderr("rackd: running", 30s)) {
      ADD_FAILURE() << p->err();
      return nullptr;
    }
    return p;
  }
  static void stop(Process& p) {
    p.signal(SIGTERM);
    EXPECT_EQ(p.wait_exit(30s), std::optional<int>(0)) << p.err();
  }
  RunResult ctl(std::vector<std::string> args) {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url(), "--discover-ms", "3000"});
    return run(args, 30s);
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::filesystem::path host_file_ = dir_.write("host.yaml", kHost);
};

TEST_F(LcmToolsTest, LoggerRecordsAndLogplayerReplaysIntoAHost) {
  const std::string logger = find_tool("lcm-logger");
  const std::string player = find_tool("lcm-logplayer");
  if (logger.empty() || player.empty()) GTEST_SKIP() << "lcm-logger/lcm-logplayer not installed (liblcm-bin)";
  const std::string log = (dir_.path() / "session.lcmlog").string();

  // Record a session: the operator sets two parameters.
  auto host = start_rackd("rackd-recorded");
  ASSERT_NE(host, nullptr);
  Process rec({logger, "--lcm-url=" + bus_.url(), "-f", log}, dir_.path(), "logger");
  std::this_thread::sleep_for(500ms);  // the logger has joined
  ASSERT_EQ(ctl({"set-param", "generator", "amplitude", "6.5"}).exit_code, 0);
  ASSERT_EQ(ctl({"set-param", "generator", "frequency_hz", "1.25"}).exit_code, 0);
  std::this_thread::sleep_for(500ms);
  rec.signal(SIGINT);
  ASSERT_TRUE(rec.wait_exit(10s).has_value()) << rec.err();
  stop(*host);
  ASSERT_GT(std::filesystem::file_size(log), 0u);

  // The recording holds our channels: lcm-logplayer -v lists what it plays.
  const RunResult listing = run({player, "-v", "-s", "100", "--lcm-url=udpm://239.255.76.67:1?ttl=0", log}, 30s);
  EXPECT_TRUE(contains(listing.out + listing.err, "TIMS")) << listing.describe();
  EXPECT_TRUE(contains(listing.out + listing.err, "TIMS_ANNOUNCE")) << listing.describe();

  // A fresh host starts with the file's values; the replay configures it as in the session.
  host = start_rackd("rackd-replayed");
  ASSERT_NE(host, nullptr);
  RunResult p = ctl({"params", "generator", "--json"});
  ASSERT_EQ(p.exit_code, 0) << p.describe();
  EXPECT_TRUE(contains(p.out, "\"name\":\"amplitude\",\"kind\":\"float\",\"value\":2}")) << p.describe();
  const RunResult play = run({player, "--lcm-url=" + bus_.url(), log}, 60s);
  ASSERT_EQ(play.exit_code, 0) << play.describe();
  p = ctl({"params", "generator", "--json"});
  ASSERT_EQ(p.exit_code, 0) << p.describe();
  EXPECT_TRUE(contains(p.out, "\"name\":\"amplitude\",\"kind\":\"float\",\"value\":6.5")) << p.describe();
  EXPECT_TRUE(contains(p.out, "\"name\":\"frequency_hz\",\"kind\":\"float\",\"value\":1.25")) << p.describe();
  EXPECT_TRUE(host->running());
  stop(*host);
}

}  // namespace
}  // namespace rack::test
