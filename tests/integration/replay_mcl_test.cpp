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
#include <numbers>
#include <regex>
#include <sstream>
#include <thread>
#include <vector>
#include <algorithm>

#include "mini_json.h"
#include "process.h"
#include "shipped_host.h"
#include "rack/rt/memory.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

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
  RackdOnBus host;
  // The shipped host file with absolute paths and 4x speed (40 s of log in 10 s).
  const std::string text = std::regex_replace(shipped_host_text("replay_carmen.yaml"), std::regex("speed: 1.0"),
                                              "speed: 4.0");
  ASSERT_TRUE(host.start(host.write("replay.yaml", text), {"--crash-dir", host.dir().path().string()}));
  Process& rackd = host.rackd();
  std::this_thread::sleep_for(11s);  // the log plays out

  double last_scan = 0;
  const auto truth = read_truth(kConfigs + "/logs/office_tour.clf", last_scan);
  ASSERT_TRUE(truth.count(last_scan) == 1) << "no TRUEPOS at the last scan's time " << last_scan;
  const Truth end = truth.at(last_scan);
  auto estimate = [&](const std::string& name) {
    const RunResult r = host.ctl({"get-data", name});
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    const auto j = parse_json(r.out);
    const Json* d = j ? j->get("data") : nullptr;
    const Json* x = d != nullptr ? d->get("x") : nullptr;
    const Json* y = d != nullptr ? d->get("y") : nullptr;
    EXPECT_TRUE(x != nullptr && y != nullptr) << r.out;
    return Truth{x != nullptr ? x->number : 1e9, y != nullptr ? y->number : 1e9};
  };
  // Every task reports its execution time, triggered ones too: MCL's update time.
  {
    const RunResult r = host.ctl({"status", "mcl"});
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    EXPECT_NE(r.out.find("triggered"), std::string::npos) << r.out;
    EXPECT_TRUE(std::regex_search(
        r.out,
        std::regex("execution time +p50 [0-9.]+ (ns|us|ms|s), p99 [0-9.]+ (ns|us|ms|s), max [0-9.]+ (ns|us|ms|s)")))
        << r.out;
    const RunResult j = host.ctl({"status", "scan2d", "--json"});
    const auto json = parse_json(j.out);
    const Json* exec = json ? json->get("execution_us") : nullptr;
    const Json* samples = exec != nullptr ? exec->get("samples") : nullptr;
    ASSERT_TRUE(samples != nullptr) << j.out;
    EXPECT_GT(samples->number, 100.0) << j.out;  // one cycle per scan at least (200 scans played)
    const Json* p99 = exec->get("p99");
    ASSERT_TRUE(p99 != nullptr) << j.out;
    EXPECT_GT(p99->number, 0.0) << j.out;
  }
  const Truth mcl = estimate("mcl");
  EXPECT_LT(std::hypot(mcl.x - end.x, mcl.y - end.y), 0.15)
      << "MCL at (" << mcl.x << ", " << mcl.y << "), truth (" << end.x << ", " << end.y << ")\n"
      << rackd.err();
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

namespace rack::test {
namespace {

struct Pose {
  double t = 0, x = 0, y = 0, phi = 0;
};
std::vector<Pose> read_trajectory(const std::string& path) {
  std::vector<Pose> out;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    Pose p;
    if (ls >> p.t >> p.x >> p.y >> p.phi) out.push_back(p);
  }
  return out;
}

// Runs configs/replay_carmen_mcl.yaml at `speed` (0: as fast as paced) until rackd
// stops by itself (exit_when_done) and returns the trajectory written.
std::vector<Pose> run_evaluation(const std::string& speed, std::string& err) {
  RackdOnBus host;
  std::string text = std::regex_replace(shipped_host_text("replay_carmen_mcl.yaml"), std::regex("speed: 0 "),
                                        "speed: " + speed + " ");
  const std::string out = (host.dir().path() / "trajectory.txt").string();
  text = std::regex_replace(text, std::regex("file: /tmp/trajectory.txt"), "file: " + out);
  // It stops by itself (exit_when_done): no wait for "running".
  EXPECT_TRUE(host.start(host.write("replay_mcl.yaml", text), {"--crash-dir", host.dir().path().string()}, false));
  Process& rackd = host.rackd();
  const auto code = rackd.wait_exit(120s);
  err = rackd.err();
  EXPECT_EQ(code, std::optional<int>(0)) << "rackd did not stop by itself after the log\n" << err;
  return read_trajectory(out);
}

// The evaluation host file as a user runs it: the whole log, MCL on every scan, the
// trajectory in the log's own time, the error against the reference printed, and
// rackd stopping by itself. As fast as paced and in real time at 4x (a clock, with
// the pace on top) give the same trajectory.
TEST(ReplayMclTest, EvaluationHostFileWritesTheSameTrajectoryAtAnySpeed) {
  Watchdog watchdog(300s, "ReplayMclTest.Evaluation");
  std::string err_fast, err_clock;
  const std::vector<Pose> fast = run_evaluation("0", err_fast);
  const std::vector<Pose> clocked = run_evaluation("4", err_clock);
  // Every scan of the log has an estimate, at the scan's own log time.
  double last_scan = 0;
  const auto truth = read_truth(kConfigs + "/logs/office_tour.clf", last_scan);
  ASSERT_EQ(fast.size(), 200U) << err_fast;
  EXPECT_NEAR(fast.front().t, 1000.0, 1e-9);
  EXPECT_NEAR(fast.back().t, last_scan, 1e-9);
  for (std::size_t k = 0; k < fast.size(); ++k) {
    EXPECT_NEAR(fast[k].t, 1000.0 + 0.2 * static_cast<double>(k), 1e-6) << "pose " << k;
  }
  EXPECT_TRUE(std::regex_search(err_fast, std::regex("200 poses written to .*ATE RMSE 0\\.0[0-9]+ m, rotation RMSE "
                                                     "[0-9.]+ deg, lost 0 of 200 reference poses")))
      << err_fast;
  // Speed does not change what MCL sees: every scan, each with the same odometry
  // (ReplayComponentTest checks that bit for bit), and the filter draws only from its
  // own generator, seeded by the host file's `seed: 1` (the likelihood split over two
  // threads writes each particle's value from one thread): the same trajectory, pose
  // for pose, at any speed.
  ASSERT_EQ(clocked.size(), fast.size()) << err_clock;
  double worst = 0;
  for (std::size_t k = 0; k < fast.size(); ++k) {
    EXPECT_EQ(clocked[k].t, fast[k].t);
    worst = std::max({worst, std::hypot(clocked[k].x - fast[k].x, clocked[k].y - fast[k].y),
                      std::fabs(std::remainder(clocked[k].phi - fast[k].phi, 2.0 * std::numbers::pi))});
  }
  EXPECT_LE(worst, 1e-9) << "largest difference between the speed-0 and speed-4 estimates of one scan (m or rad)";
  EXPECT_TRUE(std::regex_search(err_clock, std::regex("200 poses written to .*ATE RMSE 0\\.0[0-9]+ m, rotation RMSE "
                                                      "[0-9.]+ deg, lost 0 of 200 reference poses")))
      << err_clock;
}

}  // namespace
}  // namespace rack::test
