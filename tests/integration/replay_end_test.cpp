// Integration: a CARMEN replay that reaches the end of its log (issue 21 item 2). Each
// replay says so once (GDOS info), ends its stream, and the pipeline behind it
// (Odometry, Scan2D, MCL, Position) stays ENABLED and quiet: no ERROR, no retry every
// second. A tool subscribing afterwards is told "end of stream" instead of waiting.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <optional>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "process.h"
#include "shipped_host.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

std::size_t count_of(const std::string& text, const std::string& part) {
  std::size_t n = 0;
  for (auto at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

TEST(ReplayEndTest, TheEndOfTheLogIsSaidOnceAndThePipelineStaysEnabled) {
  Watchdog watchdog(60s, "ReplayEndTest");
  RackdOnBus host;
  // The shipped host file, copied elsewhere (absolute paths), at 10x: 40 s of log in 4 s.
  const std::string text = std::regex_replace(shipped_host_text("replay_carmen.yaml"), std::regex("speed: 1.0"),
                                              "speed: 10.0");
  ASSERT_TRUE(host.start(host.write("replay.yaml", text), {"--crash-dir", host.dir().path().string()}));
  Process& rackd = host.rackd();
  ASSERT_TRUE(rackd.wait_for_stderr("scans played from", 20s)) << rackd.err();
  ASSERT_TRUE(rackd.wait_for_stderr("odometry records played from", 10s)) << rackd.err();
  // Three of the old retry periods (1 s each) go by: nothing may fail in them.
  std::this_thread::sleep_for(3500ms);
  const std::string err = rackd.err();
  EXPECT_EQ(count_of(err, ": end of log: "), 2u) << "each replay says it once\n" << err;
  EXPECT_EQ(count_of(err, "-> ERROR"), 0u) << err;
  EXPECT_EQ(count_of(err, "retry succeeded"), 0u) << err;
  for (const char* consumer : {"Odometry(0/0): end of stream: every input ended", "Scan2D(0/0): end of stream",
                               "MCL(0/0): end of stream", "Position(0/0): end of stream"}) {
    EXPECT_EQ(count_of(err, consumer), 1u) << consumer << "\n" << err;
  }
  // MCL says at info level when it has converged: once (from the INIT of ON).
  EXPECT_EQ(count_of(err, "MCL(0/0): converged at ("), 1u) << err;
  const auto ctl = [&](std::vector<std::string> args) { return host.ctl(std::move(args)); };
  for (const char* name : {"chassis", "ladar", "odometry", "scan2d", "mcl", "position"}) {
    const RunResult r = ctl({"status", name, "--json"});
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    EXPECT_NE(r.out.find("\"state\":\"ENABLED\""), std::string::npos) << name << ": " << r.out;
  }
  // A consumer that comes now is told at once that nothing more comes.
  const RunResult watch = ctl({"watch", "odometry", "--count", "5"});
  EXPECT_EQ(watch.exit_code, 0) << watch.describe();
  EXPECT_NE(watch.err.find("end of stream (no more samples)"), std::string::npos) << watch.describe();
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), std::optional<int>(0)) << rackd.err();
}

}  // namespace
}  // namespace rack::test
