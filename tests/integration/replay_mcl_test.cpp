// The replay host file (configs/replay_carmen.yaml) in a real rackd: the shipped CARMEN
// log plays through ChassisReplay -> Odometry -> Scan2D <- LadarReplay -> MCL ->
// Position, here at 4x speed; rackctl reads MCL's and Position's estimates at the end
// and they must match the log's ground truth (its TRUEPOS lines). MCL's priority-0 data
// task allocates without mode-switch reports.
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <thread>

#include "mini_json.h"
#include "process.h"
#include "rack/rt/memory.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

struct Truth {
  double x = 0, y = 0;
};

// TRUEPOS by log time, and the time of the last laser line.
std::map<double, Truth> read_truth(const std::string& log, double& last_scan_time) {
  std::map<double, Truth> truth;
  std::ifstream in(log);
  for (std::string line; std::getline(in, line);) {
    std::istringstream ls(line);
    std::string kind;
    ls >> kind;
    if (kind == "TRUEPOS") {
      double x, y, th, ox, oy, oth, t;
      ls >> x >> y >> th >> ox >> oy >> oth >> t;
      truth[t] = {x, y};
    } else if (kind == "ROBOTLASER1") {
      // The ipc_timestamp is the third field from the end.
      std::vector<std::string> f;
      for (std::string w; ls >> w;) f.push_back(w);
      last_scan_time = std::stod(f[f.size() - 3]);
    }
  }
  return truth;
}

TEST(ReplayMclTest, ShippedLogLocalisesThroughTheWholePipeline) {
  Watchdog watchdog(100s, "ReplayMclTest");
  TempDir dir;
  LcmBus bus;
  // The shipped host file with absolute paths and 4x speed (40 s of log in 10 s).
  std::string host = read_file(kConfigs + "/replay_carmen.yaml");
  host = std::regex_replace(host, std::regex("configs/"), kConfigs + "/");
  host = std::regex_replace(host, std::regex("speed: 1.0"), "speed: 4.0");
  const std::string path = dir.write("replay.yaml", host).string();
  Process rackd({kRackd, path, "--lcm", bus.url(), "--crash-dir", dir.path().string()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  std::this_thread::sleep_for(11s);  // the log plays out

  double last_scan = 0;
  const auto truth = read_truth(kConfigs + "/logs/office_tour.clf", last_scan);
  ASSERT_TRUE(truth.count(last_scan) == 1) << "no TRUEPOS at the last scan's time " << last_scan;
  const Truth end = truth.at(last_scan);
  auto estimate = [&](const std::string& name) {
    const RunResult r =
        run({kRackctl, "--lcm", bus.url(), "--discover-ms", "3000", "get-data", name}, 30s);
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    const auto j = parse_json(r.out);
    const Json* d = j ? j->get("data") : nullptr;
    const Json* x = d != nullptr ? d->get("x") : nullptr;
    const Json* y = d != nullptr ? d->get("y") : nullptr;
    EXPECT_TRUE(x != nullptr && y != nullptr) << r.out;
    return Truth{x != nullptr ? x->number : 1e9, y != nullptr ? y->number : 1e9};
  };
  const Truth mcl = estimate("mcl");
  EXPECT_LT(std::hypot(mcl.x - end.x, mcl.y - end.y), 0.15)
      << "MCL at (" << mcl.x << ", " << mcl.y << "), truth (" << end.x << ", " << end.y << ")\n" << rackd.err();
  // Position: re-anchored by MCL's UPDATEs, carried on by odometry to the last ODOM
  // (0.1 s after the last scan at 0.5 m/s).
  const Truth pos = estimate("position");
  EXPECT_LT(std::hypot(pos.x - end.x, pos.y - end.y), 0.2) << "Position at (" << pos.x << ", " << pos.y << ")";
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), 0) << rackd.err();
  // MCL allocates in every update: its data task runs at priority 0, which is not
  // real-time, so mode-switch detection (on for the RT tasks) leaves it alone.
  // (A sanitizer build has no allocation hooks: ALLOC is off there.)
  if (!rack::rt::kThreadSanitizer) {
    EXPECT_NE(rackd.err().find("ALLOC on"), std::string::npos) << rackd.err();
  }
  EXPECT_EQ(rackd.err().find("MODE SWITCH"), std::string::npos) << rackd.err();
}

}  // namespace
}  // namespace rack::test
