// GridPlanner (components/path/planner.h): A* on the inflated map, waypoints for the
// Path spline. Synthetic maps with one wall, and the shipped office map.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "path/path.h"
#include "path/planner.h"
#include "rack/maps/occupancy_map.h"

namespace rack {
namespace {

using components::GridPlanner;
using components::Path;

constexpr double kRes = 0.05;

// A 10 m x 6 m room (walls round it), with a wall at x = 5 from y = 0 up to `wall_top`,
// and, when gap_from < gap_to, a gap in that wall between those y.
maps::OccupancyMap room(double wall_top, double gap_from = 0.0, double gap_to = 0.0) {
  const int w = 200, h = 120;
  std::vector<float> occ(static_cast<std::size_t>(w * h), 0.0F);
  for (int iy = 0; iy < h; ++iy) {
    for (int ix = 0; ix < w; ++ix) {
      const double x = (ix + 0.5) * kRes, y = (iy + 0.5) * kRes;
      const bool border = ix == 0 || iy == 0 || ix == w - 1 || iy == h - 1;
      const bool wall = std::abs(x - 5.0) < 0.1 && y < wall_top && !(y > gap_from && y < gap_to);
      if (border || wall) occ[static_cast<std::size_t>(iy * w + ix)] = 1.0F;
    }
  }
  return maps::OccupancyMap(w, h, kRes, 0.0, 0.0, 0.0, std::move(occ));
}

// The spline the pilot drives (Path::make_path at 5 cm) and its least clearance.
double spline_clearance(const GridPlanner& planner, const interfaces::PathMake& w, double& max_y) {
  static interfaces::PathData spline;
  const char* why = Path::make_path(w, kRes, spline);
  EXPECT_EQ(why, nullptr) << why;
  double least = 1e9;
  max_y = -1e9;
  for (uint32_t i = 0; i < spline.point_count; ++i) {
    least = std::min(least, planner.clearance(spline.x[i], spline.y[i]));
    max_y = std::max(max_y, static_cast<double>(spline.y[i]));
  }
  return least;
}

TEST(PlannerTest, DestinationBehindAWallGoesRoundIt) {
  GridPlanner planner;
  planner.set_map(room(4.5));
  interfaces::PathMake w;
  const GridPlanner::Options opt{.radius = 0.4, .comfort = 0.3};
  const auto r = planner.plan(2.0, 1.0, 8.0, 1.0, opt, w);
  ASSERT_EQ(r.error, nullptr) << r.error;
  ASSERT_GE(w.count, 3U);  // at least one turn: not the straight line through the wall
  EXPECT_DOUBLE_EQ(w.x[0], 2.0);
  EXPECT_DOUBLE_EQ(w.y[w.count - 1], 1.0);
  EXPECT_GT(r.length, 2 * std::hypot(3.0, 3.5));  // up past the wall's end (y 4.5) and down again
  double max_y = 0.0;
  // The spline keeps the robot's radius from every wall (half a cell of rounding).
  EXPECT_GE(spline_clearance(planner, w, max_y), opt.radius - kRes / 2);
  EXPECT_GT(max_y, 4.5 + opt.radius);  // it went round the wall's end
}

TEST(PlannerTest, UnreachableDestinationIsRefusedWithTheReason) {
  GridPlanner planner;
  planner.set_map(room(7.0));  // the wall closes the room off
  interfaces::PathMake w;
  const auto r = planner.plan(2.0, 1.0, 8.0, 1.0, {}, w);
  ASSERT_NE(r.error, nullptr);
  EXPECT_NE(std::string(r.error).find("cut off"), std::string::npos) << r.error;
  EXPECT_EQ(w.count, 0U);
  EXPECT_GT(r.expanded, 1000U);  // it searched the whole west half
  // Destinations in a wall, too near one, outside the map.
  EXPECT_NE(std::string(planner.plan(2.0, 1.0, 5.0, 1.0, {}, w).error).find("in a wall"), std::string::npos);
  EXPECT_NE(std::string(planner.plan(2.0, 1.0, 4.7, 1.0, {}, w).error).find("closer to a wall"), std::string::npos);
  EXPECT_NE(std::string(planner.plan(2.0, 1.0, 30.0, 1.0, {}, w).error).find("outside the map"), std::string::npos);
}

TEST(PlannerTest, InflationDecidesWhetherTheRobotFitsThroughAGap) {
  GridPlanner planner;
  planner.set_map(room(7.0, 2.0, 2.8));  // a 0.8 m gap (cells: 0.8 m, 16 cells)
  interfaces::PathMake w;
  const auto small = planner.plan(2.0, 1.0, 8.0, 1.0, {.radius = 0.3, .comfort = 0.2}, w);
  ASSERT_EQ(small.error, nullptr) << small.error;
  double max_y = 0.0;
  EXPECT_GE(spline_clearance(planner, w, max_y), 0.3 - kRes / 2);
  EXPECT_LT(max_y, 4.0);  // through the gap
  const auto big = planner.plan(2.0, 1.0, 8.0, 1.0, {.radius = 0.45, .comfort = 0.2}, w);
  ASSERT_NE(big.error, nullptr);  // 0.9 m does not fit through 0.8 m
  EXPECT_NE(std::string(big.error).find("cut off"), std::string::npos);
}

TEST(PlannerTest, ObstaclesTheScannerSeesAreAvoidedAndCleared) {
  GridPlanner planner;
  planner.set_map(room(7.0, 2.0, 3.0));
  interfaces::PathMake w;
  const GridPlanner::Options opt{.radius = 0.3, .comfort = 0.2};
  ASSERT_EQ(planner.plan(2.0, 1.0, 8.0, 1.0, opt, w).error, nullptr);
  planner.add_obstacle(5.0, 2.5, opt.radius);  // someone stands in the gap
  const auto r = planner.plan(2.0, 1.0, 8.0, 1.0, opt, w);
  ASSERT_NE(r.error, nullptr);
  EXPECT_NE(std::string(r.error).find("obstacles the scanner sees"), std::string::npos);
  planner.clear_obstacles();
  EXPECT_EQ(planner.plan(2.0, 1.0, 8.0, 1.0, opt, w).error, nullptr);
}

TEST(PlannerTest, ARobotTooCloseToAWallStartsFromTheNearestCellWithRoom) {
  GridPlanner planner;
  planner.set_map(room(4.5));
  interfaces::PathMake w;
  const auto r = planner.plan(4.7, 1.0, 2.0, 1.0, {.radius = 0.4, .comfort = 0.3}, w);
  ASSERT_EQ(r.error, nullptr) << r.error;
  EXPECT_TRUE(r.start_moved);
  EXPECT_DOUBLE_EQ(w.x[0], 4.7);  // the way still starts where the robot is
}

TEST(PlannerTest, OfficeMapFromTheCorridorIntoASouthRoom) {
  auto loaded = maps::load_map(std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml");
  ASSERT_TRUE(loaded.ok()) << loaded.error_text();
  GridPlanner planner;
  planner.set_map(*loaded.map);
  interfaces::PathMake w;
  const GridPlanner::Options opt{.radius = 0.44, .comfort = 0.3};
  // From the corridor (4, 7.2) into the room x = 7..13, y = 0..6 (door x = 9..10.2),
  // beside the table at (10, 3).
  EXPECT_NE(planner.plan(4.0, 7.2, 10.0, 3.0, opt, w).error, nullptr);  // on the table
  const auto r = planner.plan(4.0, 7.2, 11.5, 2.5, opt, w);
  ASSERT_EQ(r.error, nullptr) << r.error;
  double max_y = 0.0;
  EXPECT_GE(spline_clearance(planner, w, max_y), opt.radius - kRes / 2);
  // Somewhere the way crosses y = 6 (the wall) inside the door.
  interfaces::PathData spline;
  ASSERT_EQ(Path::make_path(w, kRes, spline), nullptr);
  bool crossed = false;
  for (uint32_t i = 1; i < spline.point_count; ++i) {
    if ((spline.y[i - 1] - 6.0F) * (spline.y[i] - 6.0F) <= 0.0F) {
      crossed = true;
      EXPECT_GT(spline.x[i], 9.0F);
      EXPECT_LT(spline.x[i], 10.2F);
    }
  }
  EXPECT_TRUE(crossed);
}

}  // namespace
}  // namespace rack
