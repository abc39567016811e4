// Integration: rackctl graph and alloc (issue 25): a deployment from its host files
// offline (configs/two_robots/), priority inversions flagged, reader errors at their
// file:line:col, and the live view against a real rackd on a private bus (its
// components' state, utilisation and worst wake-up latency; a host that does not
// answer marked stale).
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

TEST(GraphTest, TwoRobotsOfflineAsDot) {
  Watchdog watchdog(30s, "GraphTest");
  const RunResult r = run({kRackctl, "graph", kConfigs + "/two_robots/"}, 20s);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("digraph deployment {", 0), 0u) << r.out;
  // Robot 1's producer feeds a consumer on its own bus and one on robot 2 across the
  // fleet link (through both system routers).
  EXPECT_NE(r.out.find("label=\"source, 10 ms\\nvia robot1\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("label=\"source, 10 ms\\nvia robot1 > fleet > robot2\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("base-station (top_router, host_id 0)"), std::string::npos) << r.out;
  const RunResult j = run({kRackctl, "graph", "--format", "json", kConfigs + "/two_robots/"}, 20s);
  ASSERT_EQ(j.exit_code, 0) << j.err;
  EXPECT_NE(j.out.find("\"networks\":[\"robot1\",\"fleet\",\"robot2\"]"), std::string::npos) << j.out;
}

TEST(GraphTest, AllocFlagsInversionsAndReportsErrorsAtTheirLine) {
  Watchdog watchdog(30s, "GraphTest");
  TempDir dir;
  const auto file = dir.write(
      "host.yaml",
      "host: inv\n"
      "components:\n"
      "  - {name: gen, class: Generator, data_task: {priority: 40, period_ms: 5, cpu: 0}}\n"
      "  - {name: mon, class: Monitor, data_task: {priority: 45, cpu: 0}, params: {source: gen}}\n");
  const RunResult r = run({kRackctl, "alloc", file.string()}, 20s);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("  cpu 0\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("! consumer above its producer on cpu 0: 'mon' (data p45) reads 'gen' (data p40)"),
            std::string::npos)
      << r.out;
  const auto bad = dir.write("bad.yaml",
                             "host: bad\ncomponents:\n  - {name: g, class: Generator, data_task: {priority: x}}\n");
  const RunResult e = run({kRackctl, "graph", bad.string()}, 20s);
  EXPECT_EQ(e.exit_code, 1);
  EXPECT_NE(e.err.find(bad.string() + ":3:55: 'priority' must be an integer 0..99"), std::string::npos) << e.err;
  EXPECT_NE(e.out.find("color=red"), std::string::npos) << e.out;  // the host drawn as faulty
  const RunResult missing = run({kRackctl, "graph", (dir.path() / "nothing.yaml").string()}, 20s);
  EXPECT_EQ(missing.exit_code, 2) << missing.err;
}

TEST(GraphTest, LiveShowsMeasurementsAndStaleHosts) {
  Watchdog watchdog(60s, "GraphTest");
  LcmBus bus;
  TempDir dir;
  Process rackd({kRackd, kConfigs + "/demo.yaml", "--lcm", bus.url()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  // A second host in the deployment that never runs.
  const auto absent = dir.write("absent.yaml",
                                "host: absent\nsystem: 7\ncomponents:\n"
                                "  - {name: far, class: Monitor, params: {source: \"Generator(0/0)\"}}\n");
  // The demo's monitor switches the generator on; wait until it has run cycles.
  std::string out;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    const RunResult r = run({kRackctl, "--lcm", bus.url(), "--discover-ms", "1500", "alloc", "--live",
                             kConfigs + "/demo.yaml", absent.string()},
                            30s);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    out = r.out;
    if (out.find("ENABLED") != std::string::npos && out.find(" us ") != std::string::npos) break;
    std::this_thread::sleep_for(300ms);
  }
  EXPECT_NE(out.find("absent (" + absent.string() + ", system 7)  STALE: did not answer discovery"), std::string::npos)
      << out;
  EXPECT_EQ(out.find("demo (" + kConfigs + "/demo.yaml, system 0)  STALE"), std::string::npos) << out;
  // The generator's data task: period 10 ms, a utilisation and a worst wake-up latency.
  EXPECT_NE(out.find("generator            data  10 ms      "), std::string::npos) << out;
  const auto gen = out.find("generator            data");
  ASSERT_NE(gen, std::string::npos) << out;
  const std::string row = out.substr(gen, out.find('\n', gen) - gen);
  EXPECT_NE(row.find('%'), std::string::npos) << row;
  EXPECT_NE(row.find(" us "), std::string::npos) << row;
  EXPECT_NE(row.find("ENABLED"), std::string::npos) << row;
  const RunResult g = run({kRackctl, "--lcm", bus.url(), "--discover-ms", "1500", "graph", "--live",
                           kConfigs + "/demo.yaml", absent.string()},
                          30s);
  ASSERT_EQ(g.exit_code, 0) << g.err;
  EXPECT_NE(g.out.find("STALE: did not answer discovery"), std::string::npos) << g.out;
  EXPECT_NE(g.out.find("ENABLED, util "), std::string::npos) << g.out;
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(30s), std::optional<int>(0)) << rackd.err();
}

}  // namespace
}  // namespace rack::test
