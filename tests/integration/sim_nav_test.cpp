// Integration: the simulated robot (configs/sim_nav.yaml) in the real rackd, driven
// by the real rackctl over TiMS/LCM, each test on its own LCM bus with a watchdog.
//
// Asserts behaviour only (states, data, exit codes); waits are generous bounds.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "shipped_host.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class SimNavTest : public ::testing::Test {
 protected:
  SimNavTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  // configs/sim_nav.yaml with its map paths made absolute (the shipped file names
  // them relative to its own folder, and the copy is written elsewhere), optionally
  // with the ladar's map replaced.
  std::string host_file(const std::string& ladar_map = "") {
    std::string text = read_file(kConfigs + "/sim_nav.yaml");
    const std::string rel = "map: maps/office.yaml";
    const std::string abs = "map: " + kConfigs + "/maps/office.yaml";
    int replaced = 0;
    for (auto at = text.find(rel); at != std::string::npos; at = text.find(rel, at + 1)) {
      // The second occurrence is the ladar's.
      text.replace(at, rel.size(), ++replaced == 2 && !ladar_map.empty() ? "map: " + ladar_map : abs);
    }
    EXPECT_EQ(replaced, 3) << "sim_nav.yaml names the map for the chassis, the ladar and the pilot";
    return dir_.write("sim_nav.yaml", text).string();
  }
  void start(const std::string& path) {
    ASSERT_TRUE(host_.start(path));
    rackd_ = &host_.rackd();
  }
  RunResult ctl(std::vector<std::string> args) { return host_.ctl(std::move(args)); }
  // The `data` object of `rackctl get-data NAME`.
  std::optional<Json> data(const std::string& name) {
    const RunResult r = ctl({"get-data", name});
    if (r.exit_code != 0) return std::nullopt;
    auto j = parse_json(r.out);
    if (!j || !j->at("data").is_object()) return std::nullopt;
    return j->at("data");
  }
  double number(const std::string& name, const std::string& field) {
    const auto d = data(name);
    return d && d->at(field).is_number() ? d->at(field).number : -1e9;
  }
  // The robot's waits: process.h's, with room for a robot driving across the map.
  template <typename Pred>
  static bool eventually(Pred pred, std::chrono::milliseconds bound = 30s) {
    return test::eventually(pred, bound);
  }

  Watchdog watchdog_;
  RackdOnBus host_;  // stopped (SIGTERM, exit 0) when the test ends
  const TempDir& dir_ = host_.dir();
  Process* rackd_ = nullptr;  // once started
};

TEST_F(SimNavTest, TheShippedHostFilesAreValid) {
  const auto r = run({kRackd, "--check", host_file()}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

// Numbers for people: the pilot's mode and status and the chassis' active pilot by
// name in get-data's "names", beside the raw values in "data".
TEST_F(SimNavTest, GetDataNamesEnumsAndAddresses) {
  start(host_file());
  std::optional<Json> pilot, chassis;
  ASSERT_TRUE(eventually([&] {
    const RunResult p = ctl({"get-data", "pilot"});
    const RunResult c = ctl({"get-data", "chassis"});
    pilot = p.exit_code == 0 ? parse_json(p.out) : std::nullopt;
    chassis = c.exit_code == 0 ? parse_json(c.out) : std::nullopt;
    return pilot && chassis && pilot->at("data").at("status").number == 1 &&
           chassis->at("data").at("active_pilot").number != 0;
  })) << "the pilot never drove";
  EXPECT_EQ(pilot->at("names").at("status").string, "DRIVING");
  EXPECT_EQ(pilot->at("names").at("mode").string, "FOLLOW_PATH");
  EXPECT_EQ(chassis->at("names").at("active_pilot").string, "Pilot(0/0)");
  EXPECT_EQ(chassis->at("data").at("active_pilot").number, 0x190000);  // the raw value stays
}

TEST_F(SimNavTest, TheMainJobsHostFileIsValidWhenMclIsBuiltIn) {
  // sim_mcl.yaml is sim_nav.yaml plus the MCL component, which another part of the
  // project provides; until it is built in, the host file cannot load.
  const auto classes = run({kRackd, "--list-classes"}, 30s);
  ASSERT_EQ(classes.exit_code, 0) << classes.describe();
  if (!contains(classes.out, "MCL  (class ")) GTEST_SKIP() << "class MCL is not built into this rackd";
  const auto r = run({kRackd, "--check", host_.write("sim_mcl.yaml", shipped_host_text("sim_mcl.yaml"))}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

TEST_F(SimNavTest, TheRobotFollowsThePathAndTakesADestinationFromRackctl) {
  start(host_file());
  // The pilot (autostart) switched the whole robot on and drives along the path.
  ASSERT_TRUE(eventually([&] { return number("pilot", "status") == 1 && number("pilot", "vx") > 0.2; }))
      << rackd_->err();
  EXPECT_EQ(number("path", "waypoint_count"), 8);
  EXPECT_EQ(number("path", "closed"), 1);
  const auto chassis = data("chassis");
  ASSERT_TRUE(chassis.has_value());
  EXPECT_EQ(chassis->at("truth_valid").number, 1);
  EXPECT_EQ(chassis->at("collisions").number, 0);
  EXPECT_EQ(chassis->at("active_pilot").number, 0x19 << 16) << "Pilot(0/0) is the active pilot";
  // The robot moved along the corridor from its start at x = 4.
  ASSERT_TRUE(eventually([&] { return number("chassis", "truth_x") > 5.0; }));

  // A destination through rackctl: the pilot drives there and reports it reached.
  RunResult r = ctl({"set-param", "pilot", "destination", "6.5,8.0"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(eventually(
      [&] {
        const auto p = data("pilot");
        return p && p->at("mode").number == 2 && p->at("target_x").number == 6.5 && p->at("status").number == 2;
      },
      60s))
      << ctl({"get-data", "pilot"}).out;
  EXPECT_NEAR(number("chassis", "truth_x"), 6.5, 0.4);
  EXPECT_NEAR(number("chassis", "truth_y"), 8.0, 0.4);
  // A malformed destination is refused where it is set (the pilot's rule, the same
  // the host file and init() apply), and the pilot keeps its destination.
  r = ctl({"set-param", "pilot", "destination", "six,eight"});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_NE(r.err.find("not \"x,y\""), std::string::npos) << r.describe();
  EXPECT_EQ(number("pilot", "bad_destinations"), 0);
  EXPECT_EQ(number("pilot", "mode"), 2);
  EXPECT_EQ(number("pilot", "target_x"), 6.5);
  r = ctl({"set-param", "pilot", "mode", "fly"});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  // Back to the path.
  r = ctl({"set-param", "pilot", "destination", ""});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(eventually([&] { return number("pilot", "mode") == 1 && number("pilot", "status") == 1; }));
  EXPECT_EQ(number("chassis", "collisions"), 0);
  // OFF stops the robot.
  ASSERT_EQ(ctl({"off", "pilot"}).exit_code, 0);
  ASSERT_TRUE(eventually([&] { return number("chassis", "vx") == 0.0 && number("chassis", "active_pilot") == 0; }));
}

// README "Simulated robot and navigation", in order: a destination by parameter, one
// behind a wall by SET_DESTINATION (planned through the door), one in a wall (refused
// with the reason), then "" back to the path after the SET_DESTINATION.
TEST_F(SimNavTest, TheReadmeWalkThroughReachesEachDestinationInOrder) {
  start(host_file());
  ASSERT_TRUE(eventually([&] { return number("pilot", "status") == 1; })) << rackd_->err();
  const auto reached = [&](double x, double y) {
    return eventually(
        [&] {
          const auto p = data("pilot");
          return p && p->at("mode").number == 2 && p->at("status").number == 2 &&
                 std::abs(p->at("target_x").number - x) < 0.01 && std::abs(p->at("target_y").number - y) < 0.01;
        },
        40s);
  };
  RunResult r = ctl({"set-param", "pilot", "destination", "10.0,8.0"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(reached(10.0, 8.0)) << ctl({"get-data", "pilot"}).out << rackd_->err();
  EXPECT_NEAR(number("chassis", "truth_x"), 10.0, 0.4);
  EXPECT_NEAR(number("chassis", "truth_y"), 8.0, 0.4);
  // Behind the corridor's south wall (y = 6): through the door at x = 9.0 .. 10.2.
  r = ctl({"send", "pilot", "SET_DESTINATION", "x=11.5", "y=2.5"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(reached(11.5, 2.5)) << ctl({"get-data", "pilot"}).out << rackd_->err();
  EXPECT_NEAR(number("chassis", "truth_x"), 11.5, 0.4);
  EXPECT_NEAR(number("chassis", "truth_y"), 2.5, 0.4);
  EXPECT_EQ(number("chassis", "collisions"), 0);
  EXPECT_TRUE(rackd_->wait_for_stderr("planned", 1s)) << rackd_->err();
  // In a wall: refused with the reason, and the robot stays where it is.
  r = ctl({"send", "pilot", "SET_DESTINATION", "x=12", "y=6"});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err + r.out, "in a wall")) << r.describe();
  EXPECT_EQ(number("pilot", "status"), 2);
  // "" after a SET_DESTINATION (the parameter's text did not change): back to the path.
  r = ctl({"set-param", "pilot", "destination", ""});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(eventually([&] { return number("pilot", "mode") == 1; }, 5s)) << ctl({"get-data", "pilot"}).out;
}

TEST_F(SimNavTest, AMissingMapStopsOnlyTheLadarAndWhatNeedsIt) {
  const std::string missing = dir_.path().string() + "/no_such_map.yaml";
  start(host_file(missing));
  // rackd says which file is missing and keeps running.
  ASSERT_TRUE(rackd_->wait_for_stderr("no_such_map.yaml", 30s)) << rackd_->err();
  const RunResult on = ctl({"on", "ladar"});
  EXPECT_EQ(on.exit_code, 1) << on.describe();
  EXPECT_TRUE(contains(on.err + on.out, "no_such_map.yaml")) << on.describe();
  // The chassis and the odometry chain run; the pilot cannot (no scans), and says so.
  ASSERT_EQ(ctl({"on", "position"}).exit_code, 0);
  ASSERT_TRUE(eventually([&] { return number("odometry", "x") > -1e9; }));
  const auto st = ctl({"status", "chassis"});
  EXPECT_EQ(st.exit_code, 0) << st.describe();
  EXPECT_TRUE(contains(st.out, "ENABLED")) << st.describe();
  const RunResult pilot_on = ctl({"on", "pilot"});
  EXPECT_EQ(pilot_on.exit_code, 1);
  // Every ERROR names its cause through the cascade: `rackctl status` and GDOS.
  EXPECT_TRUE(contains(pilot_on.err + pilot_on.out, "is in ERROR")) << pilot_on.describe();
  const RunResult ladar_status = ctl({"status", "ladar"});
  EXPECT_TRUE(contains(ladar_status.out, "reason")) << ladar_status.describe();
  EXPECT_TRUE(contains(ladar_status.out, "no_such_map.yaml")) << ladar_status.describe();
  const RunResult pilot_status = ctl({"status", "pilot"});
  EXPECT_TRUE(contains(pilot_status.out, "reason")) << pilot_status.describe();
  EXPECT_TRUE(contains(pilot_status.out, "is in ERROR")) << pilot_status.describe();
  EXPECT_TRUE(rackd_->wait_for_stderr("is in ERROR", 5s)) << rackd_->err();
  EXPECT_TRUE(rackd_->running());
}

}  // namespace
}  // namespace rack::test
