// MCL recovery: it must tell a kidnapped robot from a bad scan. On real recorded data
// (bench/data/carmen: the FHW museum log, where a crowd of visitors blocks half the
// beams for a dozen scans, and the Intel lab log; see the README there) and in the
// simulated office. All deterministic per seed (the filter's own generator). Also the
// odometry check after a global start on the UW Seattle log.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "mcl_dataset.h"
#include "mcl_sim.h"
#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"

namespace rack::mcl {
namespace {

using test::DatasetStep;
using test::SimPose;

const std::string kData = std::string(RACK_SOURCE_DIR) + "/bench/data/carmen/";

struct RealSet {
  maps::OccupancyMap map;
  std::vector<DatasetStep> steps;
};

RealSet load(const std::string& name) {
  auto m = maps::load_map(kData + name + ".yaml");
  EXPECT_TRUE(m.ok()) << m.error_text();
  auto d = test::load_dataset(kData + name + ".log.gz");
  EXPECT_TRUE(d.error.empty()) << d.error;
  return RealSet{std::move(*m.map), std::move(d.steps)};
}

MclOptions options(uint64_t seed) {
  MclOptions o;  // defaults, at the benchmark's particle count
  o.particles_min = 1000;
  o.particles_max = 1000;
  o.seed = seed;
  return o;
}

struct RunResult {
  uint64_t injections = 0;     // updates that injected
  std::size_t lost = 0;        // scans with the estimate more than 0.5 m off
  std::vector<double> errors;  // per scan, m
};

RunResult run(MclFilter& f, const std::vector<DatasetStep>& steps) {
  RunResult r;
  for (const auto& s : steps) {
    (void)f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
    const MclEstimate e = f.estimate();
    r.injections += e.injected > 0 ? 1 : 0;
    const double err = std::hypot(e.pose.x - s.truth.x, e.pose.y - s.truth.y);
    r.errors.push_back(err);
    r.lost += err > 0.5 ? 1 : 0;
  }
  return r;
}

// The robot carried from scan `from` to scan `to`: the scans jump, the odometry goes on
// from where it was with the increments of the part the robot was carried to.
std::vector<DatasetStep> kidnapped(const std::vector<DatasetStep>& all, std::size_t from, std::size_t to) {
  std::vector<DatasetStep> steps(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(from));
  const auto compose = [](const SimPose& a, const SimPose& d) {
    return SimPose{a.x + std::cos(a.phi) * d.x - std::sin(a.phi) * d.y,
                   a.y + std::sin(a.phi) * d.x + std::cos(a.phi) * d.y,
                   std::remainder(a.phi + d.phi, 2 * std::numbers::pi)};
  };
  const auto between = [](const SimPose& a, const SimPose& b) {
    const double dx = b.x - a.x, dy = b.y - a.y;
    return SimPose{std::cos(a.phi) * dx + std::sin(a.phi) * dy, -std::sin(a.phi) * dx + std::cos(a.phi) * dy,
                   std::remainder(b.phi - a.phi, 2 * std::numbers::pi)};
  };
  SimPose odo = all[from - 1].odometry;
  for (std::size_t i = to; i < all.size(); ++i) {
    DatasetStep s = all[i];
    odo = compose(odo, between(all[i - 1].odometry, all[i].odometry));
    s.odometry = odo;
    steps.push_back(std::move(s));
  }
  return steps;
}

// Scans 40..70 of FHW: visitors stand round the robot (up to 100 of 180 readings
// shorter than 1 m), the scan fit drops a hundredfold for a dozen scans in a row. The
// old injection (weighted by one scan) threw the estimate 25-40 m away here. Now: no
// injection at all over the whole log, and the estimate stays within 0.5 m through
// the crowd, in each of three seeds; and, with the odometry check, at every scan of
// the log (its stalled odometry read-outs included; MRPT alone loses 1 per seed).
TEST(MclRecoveryTest, CrowdOnRealDataDoesNotTriggerInjection) {
  const RealSet set = load("fhw");
  ASSERT_GT(set.steps.size(), 400U);
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    MclFilter f(set.map, options(seed));
    const SimPose& t0 = set.steps[0].truth;
    f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
    const RunResult r = run(f, set.steps);
    EXPECT_EQ(r.injections, 0U) << "seed " << seed;
    for (std::size_t i = 40; i <= 70; ++i) EXPECT_LT(r.errors[i], 0.5) << "seed " << seed << ", scan " << i;
    EXPECT_EQ(r.lost, 0U) << "seed " << seed;
  }
}

// The Intel lab: 910 scans of clutter, open doors and people; the odometry stalls and
// catches up (synthetic, 52 stalls). Recovery never fires, and with the odometry check
// no pose is lost (before it: 1 per seed, the stalls 0.6-0.7 m short; MRPT alone 3-4).
TEST(MclRecoveryTest, NoInjectionOverTheIntelLog) {
  const RealSet set = load("intel");
  MclFilter f(set.map, options(1));
  const SimPose& t0 = set.steps[0].truth;
  f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
  const RunResult r = run(f, set.steps);
  EXPECT_EQ(r.injections, 0U);
  EXPECT_EQ(r.lost, 0U);  // bench/RESULTS.md
}

// Kidnapping on real data: the robot is carried from a third of the FHW log to two
// thirds (9.7 m away, another part of the museum) while the odometry goes on as if it
// had made one normal step. Recovery must inject, and the estimate must come back
// within 0.5 m and stay there to the end of the log, in at least 2 of 3 seeds (seeds 1
// and 3 recovered after 46 m and 9 m when this was written, seed 2 did not; MRPT's
// filter alone recovers in none).
TEST(MclRecoveryTest, KidnapOnRealDataIsRecovered) {
  const RealSet set = load("fhw");
  const std::size_t from = set.steps.size() / 3, to = 2 * set.steps.size() / 3;
  ASSERT_GT(from, 1U);
  const std::vector<DatasetStep> steps = kidnapped(set.steps, from, to);
  int recovered = 0;
  std::string report;
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    MclFilter f(set.map, options(seed));
    const SimPose& t0 = steps[0].truth;
    f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
    const RunResult r = run(f, steps);
    EXPECT_GT(r.injections, 0U) << "seed " << seed << ": the kidnap was not noticed";
    std::size_t good_from = steps.size();
    while (good_from > from && r.errors[good_from - 1] < 0.5) --good_from;
    const bool ok = good_from < steps.size() - 20;  // within 0.5 m for the last 20+ scans
    report += " seed " + std::to_string(seed) + ": " + (ok ? "back at scan " + std::to_string(good_from) : "not back") +
              ";";
    recovered += ok ? 1 : 0;
  }
  EXPECT_GE(recovered, 2) << report;
}

// Kidnapping where uniform injection rarely found the robot again: UW Seattle, carried
// from half the log to five sixths (a few metres, into a look-alike corridor), 32 m of
// travel left. With random poses over the free space the estimate came back in 2 of
// seeds 1..6; each injected pose now the best of global_candidates random ones by the
// scan, and the long-term fit held while lost: 6 of 6, within 4-8 m (bench/RESULTS.md).
// Required: back within 0.5 m for the last 10 scans of the log in at least 5 of 6.
TEST(MclRecoveryTest, InjectionGuidedByTheScanFindsAKidnappedRobot) {
  const RealSet set = load("seattle");
  const std::size_t from = set.steps.size() / 2, to = 5 * set.steps.size() / 6;
  ASSERT_GT(from, 1U);
  const std::vector<DatasetStep> steps = kidnapped(set.steps, from, to);
  int recovered = 0;
  std::string report;
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    MclFilter f(set.map, options(seed));
    const SimPose& t0 = steps[0].truth;
    f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
    const RunResult r = run(f, steps);
    EXPECT_GT(r.injections, 0U) << "seed " << seed << ": the kidnap was not noticed";
    std::size_t good_from = steps.size();
    while (good_from > from && r.errors[good_from - 1] < 0.5) --good_from;
    const bool ok = good_from + 10 <= steps.size();
    report += " seed " + std::to_string(seed) + ": " + (ok ? "back at scan " + std::to_string(good_from) : "not back") +
              ";";
    recovered += ok ? 1 : 0;
  }
  EXPECT_GE(recovered, 5) << report;
}

// KLD-sampling shrinks the set once the filter is sure: tracking the Intel lab log from
// its first pose with 300..20000 particles (an init gives 20000), the count drops below
// 5000 within 10 updates and stays there while the estimate stays within 0.5 m. (When
// the KLD bins counted the moved particles, a 1 m step's motion noise spread them over
// hundreds of bins and the set stayed at 15000-20000: bench/RESULTS.md.)
TEST(MclRecoveryTest, KldShrinksTheSetOnceConverged) {
  const RealSet set = load("intel");
  ASSERT_GT(set.steps.size(), 120U);
  for (uint64_t seed = 1; seed <= 2; ++seed) {
    MclOptions o = options(seed);
    o.particles_min = 300;
    o.particles_max = 20000;
    MclFilter f(set.map, o);
    const SimPose& t0 = set.steps[0].truth;
    f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
    EXPECT_EQ(f.estimate().particles, 20000U);
    uint32_t most = 0;
    std::size_t lost = 0;
    for (std::size_t i = 0; i < 120; ++i) {
      const auto& s = set.steps[i];
      (void)f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
      const MclEstimate e = f.estimate();
      if (e.updates > 10) most = std::max(most, e.particles);
      lost += std::hypot(e.pose.x - s.truth.x, e.pose.y - s.truth.y) > 0.5 ? 1U : 0U;
    }
    EXPECT_LT(most, 5000U) << "seed " << seed;
    EXPECT_GE(most, 300U) << "seed " << seed;
    EXPECT_EQ(lost, 0U) << "seed " << seed;
  }
}

// In the simulated office: one scan (and three in a row) of a person standing right
// in front of the robot (all readings 0.4-0.6 m) while it tracks well: no injection,
// the estimate stays within 0.1 m.
TEST(MclRecoveryTest, BadScansInTheSimulatorDoNotTriggerInjection) {
  auto m = maps::load_map(std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml");
  ASSERT_TRUE(m.ok()) << m.error_text();
  MclOptions o;
  o.seed = 7;
  MclFilter f(*m.map, o);
  test::ScriptedRobot robot(*m.map, test::SimConfig{}, 7);
  robot.place({2.0, 8.0, 0.0});
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  uint64_t injected = 0;
  for (int i = 0; i < 240 && !robot.step_towards(14.0, 8.0); ++i) {
    test::SimScan s = robot.scan();
    if (i == 60 || (i >= 120 && i < 123)) {  // the person: a wall of short readings
      for (std::size_t k = 0; k < s.xs.size(); ++k) {
        const double a = std::atan2(s.ys[k], s.xs[k]);
        const double r = 0.4 + 0.2 * static_cast<double>(k % 5) / 4.0;
        s.xs[k] = static_cast<float>(r * std::cos(a));
        s.ys[k] = static_cast<float>(r * std::sin(a));
      }
    }
    const SimPose od = robot.odometry();
    if (f.update({od.x, od.y, od.phi}, s.xs, s.ys)) injected += f.estimate().injected;
  }
  const MclEstimate e = f.estimate();
  EXPECT_EQ(injected, 0U);
  EXPECT_LT(std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y), 0.1);
}

// An odometry catch-up after a stall (2 m between two scans, below odometry_jump) is
// real motion: applied, not dropped as a jump.
TEST(MclRecoveryTest, OdometryCatchUpIsMotionNotAJump) {
  auto m = maps::load_map(std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml");
  ASSERT_TRUE(m.ok()) << m.error_text();
  MclOptions o;
  o.seed = 9;
  MclFilter f(*m.map, o);
  test::ScriptedRobot robot(*m.map, test::SimConfig{}, 9);
  robot.place({2.0, 8.0, 0.0});
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  SimPose frozen{};
  int i = 0;
  for (; i < 400 && !robot.step_towards(12.0, 8.0); ++i) {
    const test::SimScan s = robot.scan();
    SimPose od = robot.odometry();
    if (i >= 100 && i < 140) od = frozen;  // the read-out stalls for 40 scans (2 m)
    else frozen = od;
    (void)f.update({od.x, od.y, od.phi}, s.xs, s.ys);
    if (i == 140) {
      const MclEstimate e = f.estimate();
      EXPECT_EQ(e.odometry_jumps, 0U);
      EXPECT_LT(std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y), 0.3);
    }
  }
  EXPECT_GT(i, 140);
  const MclEstimate e = f.estimate();
  EXPECT_EQ(e.odometry_jumps, 0U);
  EXPECT_LT(std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y), 0.1);
}

// The odometry check after a global start (seattle, first 200 scans, seed 1): once the
// estimate has converged the check acts at the stalled read-outs as it does when
// tracking from the reference pose. Its "scans fit as usual" guard compared with w_slow,
// which after init_global() starts at a perfect fit: the check stayed off for the first
// 100-odd updates (11 disagreements here against 17 while tracking; seed 8 was 0.52 m off
// at a stall at scan 125). Now: at least the tracking run's count less two, and no pose
// more than 0.5 m off from scan 10 on.
TEST(MclRecoveryTest, OdometryCheckWorksAfterAGlobalStartOnceConverged) {
  const RealSet set = load("seattle");
  ASSERT_GT(set.steps.size(), 200U);
  const std::vector<DatasetStep> steps(set.steps.begin(), set.steps.begin() + 200);
  uint64_t tracking = 0;
  {
    MclFilter f(set.map, options(1));
    const SimPose& t0 = steps[0].truth;
    f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
    (void)run(f, steps);
    tracking = f.estimate().odometry_disagreements;
  }
  MclOptions o = options(1);
  o.particles_min = 300;
  o.particles_max = 20000;
  MclFilter f(set.map, o);
  f.init_global();
  const RunResult r = run(f, steps);
  const uint64_t global = f.estimate().odometry_disagreements;
  std::size_t lost = 0;
  for (std::size_t i = 10; i < r.errors.size(); ++i) lost += r.errors[i] > 0.5 ? 1U : 0U;
  EXPECT_GE(tracking, 10U);
  EXPECT_GE(global + 2, tracking) << "disagreements after the global start " << global << ", tracking " << tracking;
  EXPECT_EQ(lost, 0U);
}

}  // namespace
}  // namespace rack::mcl
