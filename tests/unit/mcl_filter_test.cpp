// MCL with real MRPT on the shipped office map: tracking accuracy, global localisation,
// recovery from kidnapping, and map/option errors. The robot and its scans are
// synthesised (mcl_sim.h: ray casting the map plus noise), deterministic per seed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "mcl_sim.h"
#include "rack/core/compute_worker.h"
#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"

namespace rack::mcl {
namespace {

using test::ScriptedRobot;
using test::SimConfig;
using test::SimPose;

const std::string kOffice = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";

// A tour of the office (map frame, metres): along the corridor (y = 8), into the
// second south room through its door (x = 9.6), back, and on east.
const std::vector<std::pair<double, double>> kTour = {{2.0, 8.0}, {9.6, 8.0}, {9.6, 4.0},  {11.0, 3.0},
                                                      {9.6, 4.0}, {9.6, 8.0}, {18.0, 8.0}, {19.6, 11.5}};

class MclFilterTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto r = maps::load_map(kOffice);
    ASSERT_TRUE(r.ok()) << r.error_text();
    map_ = new maps::OccupancyMap(std::move(*r.map));
  }
  static void TearDownTestSuite() {
    delete map_;
    map_ = nullptr;
  }
  static maps::OccupancyMap* map_;
};
maps::OccupancyMap* MclFilterTest::map_ = nullptr;

struct RunStats {
  double rms = 0.0;          // position error RMS over the filter updates after settling
  double max_heading = 0.0;  // rad
  double final_error = 0.0;  // m
  int updates = 0;
};

// Drives the tour (from its first waypoint) feeding every scan to the filter.
// `settle` updates at the start are left out of the statistics.
RunStats drive(MclFilter& f, ScriptedRobot& robot, const std::vector<std::pair<double, double>>& tour, int settle,
               double max_travel = 1e9) {
  RunStats st;
  double sum_sq = 0.0;
  int n = 0;
  double travelled = 0.0;
  SimPose prev = robot.truth();
  for (std::size_t w = 1; w < tour.size() && travelled < max_travel; ++w) {
    for (int guard = 0; guard < 5000 && !robot.step_towards(tour[w].first, tour[w].second); ++guard) {
      const test::SimScan s = robot.scan();
      const SimPose o = robot.odometry();
      const bool ran = f.update({o.x, o.y, o.phi}, s.xs, s.ys);
      travelled += std::hypot(robot.truth().x - prev.x, robot.truth().y - prev.y);
      prev = robot.truth();
      if (!ran) continue;
      ++st.updates;
      const MclEstimate e = f.estimate();
      const double err = std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y);
      st.final_error = err;
      if (st.updates <= settle) continue;
      sum_sq += err * err;
      ++n;
      st.max_heading = std::max(st.max_heading, std::fabs(test::angle_diff(e.pose.phi, robot.truth().phi)));
      if (travelled >= max_travel) break;
    }
  }
  st.rms = n > 0 ? std::sqrt(sum_sq / n) : 1e9;
  return st;
}

MclOptions tracking_options(uint64_t seed) {
  MclOptions o;
  o.particles_min = 200;
  o.particles_max = 1000;
  o.seed = seed;
  return o;
}

TEST_F(MclFilterTest, TracksTheTourWithinFiveCentimetresRms) {
  for (uint64_t seed : {1U, 2U, 3U}) {
    MclFilter f(*map_, tracking_options(seed));
    ScriptedRobot robot(*map_, SimConfig{}, seed);
    robot.place({kTour[0].first, kTour[0].second, 0.0});
    f.init_pose({kTour[0].first + 0.1, kTour[0].second - 0.1, 0.05}, 0.2, 0.1);
    const RunStats st = drive(f, robot, kTour, 5);
    std::printf("seed %lu: RMS %.4f m over %d updates, max heading error %.3f rad\n", static_cast<unsigned long>(seed),
                st.rms, st.updates, st.max_heading);
    EXPECT_GT(st.updates, 100) << "seed " << seed;
    EXPECT_LT(st.rms, 0.05) << "seed " << seed << ": RMS " << st.rms << " m over " << st.updates << " updates";
    EXPECT_LT(st.max_heading, 0.1) << "seed " << seed;
  }
}

// Drives the whole tour from a global start and returns the travel (m) after which
// the estimate stayed within `tolerance` of the truth to the end (1e9: never).
double travel_to_converge(MclFilter& f, ScriptedRobot& robot, double tolerance,
                          const std::vector<std::pair<double, double>>& tour = kTour, uint32_t* injected = nullptr) {
  double travelled = 0.0, converged_at = 1e9;
  SimPose prev = robot.truth();
  for (std::size_t w = 1; w < tour.size(); ++w) {
    for (int guard = 0; guard < 5000 && !robot.step_towards(tour[w].first, tour[w].second); ++guard) {
      const test::SimScan s = robot.scan();
      const SimPose o = robot.odometry();
      travelled += std::hypot(robot.truth().x - prev.x, robot.truth().y - prev.y);
      prev = robot.truth();
      if (!f.update({o.x, o.y, o.phi}, s.xs, s.ys)) continue;
      const MclEstimate e = f.estimate();
      if (injected != nullptr) *injected += e.injected;
      const bool good = std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y) < tolerance;
      if (!good) converged_at = 1e9;
      else if (converged_at > 1e8) converged_at = travelled;
    }
  }
  return converged_at;
}

// Global localisation: particles over the whole free space, the robot drives the tour
// (about 37 m). The bar: the estimate is within 0.3 m of the truth, and stays there,
// after at most 15 m of travel in at least 8 of the 10 seeds (11..20). The office's
// corridor is long and repetitive, so a seed may need more travel (or, rarely, the
// whole tour) before a door or room tells the places apart. When this was written: 9
// of 10 with the default (5 candidates, the best kept), 9 of 10 with one candidate per
// particle; 5 seeds (11..15, 4 needed) were too few: one unlucky draw decided it.
TEST_F(MclFilterTest, GlobalLocalisationConvergesWithinFifteenMetresInMostSeeds) {
  int converged = 0;
  std::string report;
  for (uint64_t seed = 11; seed <= 20; ++seed) {
    MclOptions o;
    o.particles_min = 300;
    o.particles_max = 8000;
    o.seed = seed;
    MclFilter f(*map_, o);
    ScriptedRobot robot(*map_, SimConfig{}, seed);
    robot.place({kTour[0].first, kTour[0].second, 0.0});
    f.init_global();
    const double at = travel_to_converge(f, robot, 0.3);
    report += " seed " + std::to_string(seed) + ": " + (at < 1e8 ? std::to_string(at) + " m" : "never") + ";";
    if (at <= 15.0) ++converged;
  }
  EXPECT_GE(converged, 8) << report;
}

// Kidnapping: after tracking, the robot is carried 7.6 m along the corridor (a place
// that looks much like the one it left) without the odometry noticing. Random
// injection must bring the estimate back, to stay within 0.3 m of the truth, within
// 20 m of further travel, in each of the seeds 21..23 (seeds 21..30 recovered within
// 2..12 m when this was written).
TEST_F(MclFilterTest, RecoversFromKidnapping) {
  for (uint64_t seed = 21; seed <= 23; ++seed) {
    MclOptions o = tracking_options(seed);
    o.particles_max = 3000;
    MclFilter f(*map_, o);
    ScriptedRobot robot(*map_, SimConfig{}, seed);
    robot.place({2.0, 8.0, 0.0});
    f.init_pose({2.0, 8.0, 0.0}, 0.1, 0.05);
    const RunStats before = drive(f, robot, {{2.0, 8.0}, {8.0, 8.0}}, 3);
    ASSERT_LT(before.final_error, 0.1) << "seed " << seed;
    robot.kidnap({15.6, 8.0, 0.0});
    const std::vector<std::pair<double, double>> after = {{15.6, 8.0}, {21.0, 8.0},  {21.1, 4.0}, {21.1, 8.0},
                                                          {14.0, 8.0}, {13.6, 11.5}, {13.6, 13.5}};
    uint32_t injected = 0;
    const double at = travel_to_converge(f, robot, 0.3, after, &injected);
    EXPECT_GT(injected, 0U) << "seed " << seed << ": no particle was injected after the kidnapping";
    EXPECT_LE(at, 20.0) << "seed " << seed << ": recovered after " << at << " m (1e9: never)";
  }
}

TEST_F(MclFilterTest, NoInjectionWhileTrackingWell) {
  MclFilter f(*map_, tracking_options(31));
  ScriptedRobot robot(*map_, SimConfig{}, 31);
  robot.place({2.0, 8.0, 0.0});
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  uint32_t injected = 0;
  for (int i = 0; i < 200 && !robot.step_towards(12.0, 8.0); ++i) {
    const test::SimScan s = robot.scan();
    const SimPose od = robot.odometry();
    if (f.update({od.x, od.y, od.phi}, s.xs, s.ys) && i > 20) injected += f.estimate().injected;
  }
  EXPECT_EQ(injected, 0U);
}

// The likelihood's second thread is a compute worker the filter is given (the MCL
// component's is the executor's): it takes half of every large update, and the
// estimates are the very same as with the caller's thread alone.
TEST_F(MclFilterTest, AComputeWorkerSharesTheLikelihoodAndChangesNoEstimate) {
  MclOptions o = tracking_options(7);
  o.particles_min = o.particles_max = 2000;  // x every echo: above the 100 000 look-ups that split
  o.beams = 0;
  o.update_distance = o.update_angle = 0.0;  // every scan an update
  ComputeWorker worker;
  std::thread server([&worker] { worker.serve(); });
  MclFilter shared(*map_, o, &worker);
  MclFilter alone(*map_, o);
  ScriptedRobot robot(*map_, SimConfig{}, 7);
  robot.place({kTour[0].first, kTour[0].second, 0.0});
  shared.init_pose({kTour[0].first + 0.1, kTour[0].second - 0.1, 0.05}, 0.2, 0.1);
  alone.init_pose({kTour[0].first + 0.1, kTour[0].second - 0.1, 0.05}, 0.2, 0.1);
  int updates = 0;
  for (int guard = 0; guard < 40 && !robot.step_towards(kTour[1].first, kTour[1].second); ++guard) {
    const test::SimScan s = robot.scan();
    const SimPose odo = robot.odometry();
    ASSERT_EQ(shared.update({odo.x, odo.y, odo.phi}, s.xs, s.ys), alone.update({odo.x, odo.y, odo.phi}, s.xs, s.ys));
    const MclEstimate a = shared.estimate(), b = alone.estimate();
    ASSERT_EQ(a.pose.x, b.pose.x) << "update " << updates;
    ASSERT_EQ(a.pose.y, b.pose.y) << "update " << updates;
    ASSERT_EQ(a.pose.phi, b.pose.phi) << "update " << updates;
    ASSERT_EQ(a.particles, b.particles);
    ++updates;
  }
  worker.stop();
  server.join();
  EXPECT_EQ(updates, 40);
  EXPECT_GE(worker.jobs_served(), 40u) << "the worker's thread took half of each update";
  EXPECT_EQ(worker.jobs_inline(), 0u);
}

TEST_F(MclFilterTest, UpdatesAreGatedByTravelAndTurn) {
  MclOptions o = tracking_options(41);
  o.update_distance = 0.2;
  o.update_angle = 0.3;
  MclFilter f(*map_, o);
  ScriptedRobot robot(*map_, SimConfig{}, 41);
  robot.place({2.0, 8.0, 0.0});
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  test::SimScan s = robot.scan();
  EXPECT_TRUE(f.update({0, 0, 0}, s.xs, s.ys));     // first scan after init: always
  EXPECT_FALSE(f.update({0.1, 0, 0}, s.xs, s.ys));  // 0.1 m: gated
  EXPECT_FALSE(f.update({0.19, 0, 0.2}, s.xs, s.ys));
  // Between updates the estimate follows odometry.
  EXPECT_NEAR(f.estimate().pose.x, 2.19, 0.05);
  EXPECT_TRUE(f.update({0.21, 0, 0}, s.xs, s.ys));  // 0.21 m
  EXPECT_FALSE(f.update({0.21, 0, 0.2}, s.xs, s.ys));
  EXPECT_TRUE(f.update({0.21, 0, 0.35}, s.xs, s.ys));  // 0.35 rad
  EXPECT_EQ(f.estimate().updates, 3U);
}

// An Odometry RESET between two scans (the odometry jumps back to zero) must not throw
// the particles across the map: MCL re-anchors on the new odometry.
TEST_F(MclFilterTest, OdometryJumpIsReanchoredNotApplied) {
  MclFilter f(*map_, tracking_options(61));
  ScriptedRobot robot(*map_, SimConfig{}, 61);
  robot.place({2.0, 8.0, 0.0});
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  for (int i = 0; i < 200 && !robot.step_towards(8.0, 8.0); ++i) {  // 6 m: above odometry_jump (5 m)
    const test::SimScan s = robot.scan();
    const SimPose od = robot.odometry();
    (void)f.update({od.x, od.y, od.phi}, s.xs, s.ys);
  }
  const test::SimScan s = robot.scan();
  (void)f.update({0.0, 0.0, 0.0}, s.xs, s.ys);  // RESET: odometry back at zero, robot still
  const MclEstimate e = f.estimate();
  EXPECT_EQ(e.odometry_jumps, 1U);
  EXPECT_LT(std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y), 0.1);
}

TEST_F(MclFilterTest, KldShrinksTheParticleSetOnceLocalised) {
  MclOptions o = tracking_options(51);
  o.particles_min = 100;
  o.particles_max = 4000;
  MclFilter f(*map_, o);
  ScriptedRobot robot(*map_, SimConfig{}, 51);
  robot.place({2.0, 8.0, 0.0});
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  EXPECT_EQ(f.estimate().particles, 4000U);
  for (int i = 0; i < 40 && !robot.step_towards(8.0, 8.0); ++i) {
    const test::SimScan s = robot.scan();
    const SimPose od = robot.odometry();
    (void)f.update({od.x, od.y, od.phi}, s.xs, s.ys);
  }
  const MclEstimate e = f.estimate();
  EXPECT_LT(e.particles, 1000U);
  EXPECT_GE(e.particles, 100U);
  EXPECT_GT(e.ess, 0.0F);
  EXPECT_LE(e.ess, 1.0F);
  std::vector<float> x(50), y(50), phi(50), w(50);
  ASSERT_EQ(f.sample_particles(x, y, phi, w), 50U);
  double sum = 0;
  for (float v : w) sum += v;
  EXPECT_NEAR(sum, 1.0, 1e-4);
  EXPECT_NEAR(x[0], robot.truth().x, 0.5);
}

// global_candidates: init_global() spreads that many times particles_max poses, the
// first update weighs every one of them (no resampling before it) and keeps the
// particles_max that fit the scan best, equally weighted; the next one resamples (KLD)
// from those. Out of range is refused with the option's name.
TEST_F(MclFilterTest, GlobalCandidatesAreAllWeighedOnceThenTheBestKept) {
  MclOptions o;
  o.particles_min = 100;
  o.particles_max = 1000;
  o.global_candidates = 5;
  o.seed = 61;
  MclFilter f(*map_, o);
  f.init_global();
  EXPECT_EQ(f.estimate().particles, 5000U);
  ScriptedRobot robot(*map_, SimConfig{}, 61);
  robot.place({2.0, 8.0, 0.0});
  std::vector<uint32_t> counts;
  for (int i = 0; i < 40 && counts.size() < 2 && !robot.step_towards(8.0, 8.0); ++i) {
    const test::SimScan s = robot.scan();
    const SimPose od = robot.odometry();
    if (!f.update({od.x, od.y, od.phi}, s.xs, s.ys)) continue;
    counts.push_back(f.estimate().particles);
    if (counts.size() == 1) {  // the kept candidates are equally weighted
      std::vector<float> x(1000), y(1000), phi(1000), w(1000);
      ASSERT_EQ(f.sample_particles(x, y, phi, w), 1000U);
      for (float v : w) EXPECT_FLOAT_EQ(v, 1e-3F);
    }
  }
  ASSERT_EQ(counts.size(), 2U);
  EXPECT_EQ(counts[0], 1000U);  // the best 1000 of the 5000 candidates
  EXPECT_LE(counts[1], 1000U);
  EXPECT_GE(counts[1], 100U);
  f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
  EXPECT_EQ(f.estimate().particles, 1000U);
  for (uint32_t bad : {0U, 101U}) {
    o.global_candidates = bad;
    const char* why = check_options(o);
    ASSERT_NE(why, nullptr) << bad;
    EXPECT_NE(std::string(why).find("global_candidates"), std::string::npos) << why;
  }
}

// The odometry check (scan-to-scan): the robot drives 0.8 m per scan; at one scan the
// odometry read-out stalls (30 % of the step reported, the rest with the next scan, as
// the real logs' odometry does). Particles moved by the odometry alone fall 0.56 m
// behind at that scan, beyond what the motion model reaches; the scan matched against
// the previous one sees the whole step and part of the particles follows it. With the
// check (the default) the estimate stays within 0.2 m at the stalled scan and the
// catch-up after it, and the check disagreed there; off (odometry_check 0) the estimate
// is more than 0.3 m behind at the stalled scan. Out of range is refused by name.
TEST_F(MclFilterTest, StalledOdometryReadOutIsFollowedByTheScanMatch) {
  SimConfig cfg;
  cfg.step = 0.8;
  constexpr int kStall = 8;
  for (const double check : {0.0, MclOptions{}.odometry_check}) {
    MclOptions o = tracking_options(5);
    o.odometry_check = check;
    MclFilter f(*map_, o);
    ScriptedRobot robot(*map_, cfg, 5);
    robot.place({2.0, 8.0, 0.0});
    f.init_pose({2.0, 8.0, 0.0}, 0.05, 0.02);
    SimPose last{};
    std::vector<double> err;
    std::vector<bool> disagreed;
    for (int i = 0; i <= kStall + 1 && !robot.step_towards(14.0, 8.0); ++i) {
      const test::SimScan s = robot.scan();
      SimPose od = robot.odometry();
      if (i == kStall) {  // the stalled read-out: 30 % of the step since the last one
        od = {last.x + 0.3 * (od.x - last.x), last.y + 0.3 * (od.y - last.y),
              last.phi + 0.3 * test::angle_diff(od.phi, last.phi)};
      }
      last = od;
      ASSERT_TRUE(f.update({od.x, od.y, od.phi}, s.xs, s.ys)) << "scan " << i;
      const MclEstimate e = f.estimate();
      err.push_back(std::hypot(e.pose.x - robot.truth().x, e.pose.y - robot.truth().y));
      disagreed.push_back(e.odometry_disagreed);
    }
    ASSERT_EQ(err.size(), static_cast<std::size_t>(kStall + 2));
    std::printf("odometry_check %.1f: error before the stall %.3f m, at it %.3f m, after %.3f m\n", check,
                err[kStall - 1], err[kStall], err[kStall + 1]);
    EXPECT_LT(err[kStall - 1], 0.15) << "check " << check;
    if (check > 0) {
      EXPECT_TRUE(disagreed[kStall]);
      EXPECT_TRUE(disagreed[kStall + 1]);  // the catch-up: the odometry reports 1.36 m
      EXPECT_LT(err[kStall], 0.2);
      EXPECT_LT(err[kStall + 1], 0.2);
      EXPECT_GE(f.estimate().odometry_disagreements, 2U);
    } else {
      EXPECT_GT(err[kStall], 0.3);
      EXPECT_EQ(f.estimate().odometry_disagreements, 0U);
    }
  }
  MclOptions o;
  o.odometry_check = -1;
  ASSERT_NE(check_options(o), nullptr);
  EXPECT_NE(std::string(check_options(o)).find("odometry_check"), std::string::npos);
  o = MclOptions{};
  o.odometry_check_fraction = 1.5;
  ASSERT_NE(check_options(o), nullptr);
  EXPECT_NE(std::string(check_options(o)).find("odometry_check_fraction"), std::string::npos);
  o = MclOptions{};
  o.odometry_check_goodness = 0;
  ASSERT_NE(check_options(o), nullptr);
  EXPECT_NE(std::string(check_options(o)).find("odometry_check_goodness"), std::string::npos);
}

TEST_F(MclFilterTest, BadOptionsAreRejectedWithTheirName) {
  MclOptions o;
  o.particles_min = 500;
  o.particles_max = 100;
  try {
    MclFilter f(*map_, o);
    FAIL() << "accepted particles_max < particles_min";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("particles_max"), std::string::npos) << e.what();
  }
}

TEST_F(MclFilterTest, MapWithoutFreeCellsOrRotatedIsRejected) {
  const maps::OccupancyMap walls(10, 10, 0.1, 0.0, 0.0, 0.0, std::vector<float>(100, 1.0F));
  EXPECT_THROW(MclFilter(walls, MclOptions{}), std::invalid_argument);
  const maps::OccupancyMap rotated(10, 10, 0.1, 0.0, 0.0, 0.5, std::vector<float>(100, 0.0F));
  try {
    MclFilter f(rotated, MclOptions{});
    FAIL() << "accepted a rotated map";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("yaw"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rack::mcl
