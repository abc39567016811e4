// The simulated robot and navigation classes (ChassisSim, Odometry, Position, Scan2D,
// LadarSim, Path, Pilot), in a real in-process executor driven by TiMS messages from
// a tool mailbox (test_support.h), on the shipped office map.
//
// Timing-sensitive tests (watchdog, driving) have "Tolerant" in their names: their
// margins are generous, and each threaded test has a watchdog. They run stepped on a
// virtual clock now (the fixture's start()), so they no longer depend on the machine's
// load; the names stay (ctest's history, other branches).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include "chassis_sim/chassis_sim.h"
#include "common/pose2d.h"
#include "path/path.h"
#include "pilot/pilot.h"
#include "rack/components/class_ids.h"
#include "pilot/pilot_types.h"
#include "odometry/odometry_types.h"
#include "rack/interfaces/demo.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"
#include "rack/maps/occupancy_map.h"
#include "scan2d/scan2d.h"
#include "test_support.h"

namespace rack {
namespace {

using components::Pose2d;
using interfaces::ChassisData;
using interfaces::OdometryData;
using interfaces::PilotData;
using interfaces::PositionData;
using test::HostUnderTest;
using test::Stepping;
using test::Watchdog;
using tims::Address;
namespace msg = tims::msg;

const std::string kOffice = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";

// ---------------------------------------------------------------- host files

std::string chassis_yaml(const std::string& extra_params = "", int watchdog_ms = 300) {
  return R"(  - name: chassis
    class: ChassisSim
    instance: 0
    command_task: {priority: 40}
    data_task: {priority: 45, period_ms: 10, ring: 500}
    params: {noise_xy: 0.0, noise_phi: 0.0, noise_phi_per_m: 0.0, watchdog_ms: )" +
         std::to_string(watchdog_ms) + extra_params + R"(}
)";
}

std::string odometry_position_yaml(const std::string& position_params = "") {
  return R"(  - name: odometry
    class: Odometry
    instance: 0
    data_task: {priority: 44, ring: 1000}
    params: {chassis: chassis}
  - name: position
    class: Position
    instance: 0
    data_task: {priority: 43, ring: 200}
    params: {odometry: odometry)" +
         position_params + R"(}
)";
}

std::string ladar_scan_yaml(const std::string& map, const std::string& ladar_params = "",
                            const std::string& scan_params = "") {
  return R"(  - name: ladar
    class: LadarSim
    instance: 0
    data_task: {priority: 42, period_ms: 40, ring: 10}
    params: {chassis: chassis, map: ")" +
         map + R"(", beams: 541, fov_deg: 270, noise_sigma: 0.0)" + ladar_params + R"(}
  - name: scan2d
    class: Scan2D
    instance: 0
    data_task: {priority: 41, ring: 10}
    params: {ladar: ladar, odometry: odometry)" +
         scan_params + R"(}
)";
}

std::string host(const std::string& components) { return "system: 0\nlcm: false\ncomponents:\n" + components; }

// ---------------------------------------------------------------- helpers

struct Sample {
  wire::SampleHeader header;
  ChassisData data;
};

// Stepped (rack/core/stepper.h) unless a test asks for threads: the components run on a
// virtual clock, so "drive for 500 ms" is exactly 50 chassis cycles, and waiting for a
// condition moves the clock to the first instant it holds instead of polling.
class RobotSimTest : public ::testing::Test {
 protected:
  void start(const std::string& yaml, Stepping stepping = Stepping::kStepped) {
    stepping_ = stepping;
    host_ = std::make_unique<HostUnderTest>(yaml, nullptr, false, stepping);
  }
  // Until `pred` holds, at most `limit` (virtual time when stepped, real time polled
  // with threads). Returns whether it held.
  bool until(const std::function<bool()>& pred, std::chrono::milliseconds limit = std::chrono::milliseconds(10000)) {
    if (stepping_ == Stepping::kStepped) return h().stepper().run_until(pred, limit.count() * rt::kNsPerMs);
    return test::eventually(pred, limit);
  }
  // Lets `ms` pass: the tasks run that long (virtual time when stepped).
  void pause(int ms) {
    if (stepping_ == Stepping::kStepped) (void)h().stepper().run_for(ms * rt::kNsPerMs);
    else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
  }
  void TearDown() override {
    if (host_ && HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
  }
  HostUnderTest& h() { return *host_; }

  template <typename T>
  T newest(Address a, wire::SampleHeader* header = nullptr) {
    T d{};
    wire::SampleHeader sh;
    EXPECT_TRUE(until([&] { return h().get_data(a, sh, d); })) << "no data from " << a.str();
    if (header != nullptr) *header = sh;
    return d;
  }
  // Waits for a sample newer than `after_ns`.
  template <typename T>
  T newer_than(Address a, int64_t after_ns, wire::SampleHeader* header = nullptr) {
    T d{};
    wire::SampleHeader sh;
    EXPECT_TRUE(until([&] { return h().get_data(a, sh, d) && sh.time_ns > after_ns; }));
    if (header != nullptr) *header = sh;
    return d;
  }

  HostUnderTest::Reply claim(Address chassis, Address pilot) {
    interfaces::ChassisSetActivePilot p;
    p.pilot = pilot.raw();
    return h().call_with(chassis, interfaces::kChassisSetActivePilot, p);
  }
  HostUnderTest::Reply move(Address chassis, double vx, double omega = 0.0) {
    interfaces::ChassisMove m;
    m.vx = vx;
    m.omega = omega;
    return h().call_with(chassis, interfaces::kChassisMove, m);
  }
  Address tool() { return h().endpoint().address(); }

  std::unique_ptr<HostUnderTest> host_;
  Stepping stepping_ = Stepping::kStepped;
};

// ---------------------------------------------------------------- ChassisSim

TEST(ChassisSimRamp, AcceleratesAndBrakesWithinTheirLimits) {
  using components::ChassisSim;
  EXPECT_DOUBLE_EQ(ChassisSim::ramp(0.0, 1.0, 0.5, 2.0, 0.1), 0.05);     // speeding up: acc
  EXPECT_DOUBLE_EQ(ChassisSim::ramp(1.0, 0.0, 0.5, 2.0, 0.1), 0.8);      // braking: dec
  EXPECT_DOUBLE_EQ(ChassisSim::ramp(0.5, -1.0, 0.5, 2.0, 0.1), 0.3);     // reversing brakes first
  EXPECT_DOUBLE_EQ(ChassisSim::ramp(0.99, 1.0, 0.5, 2.0, 0.1), 1.0);     // never past the target
  EXPECT_DOUBLE_EQ(ChassisSim::ramp(-0.2, -1.0, 0.5, 2.0, 0.1), -0.25);  // backwards speeding up
}

TEST_F(RobotSimTest, OnlyTheActivePilotMayMoveAndChangingPilotStopsTheRobot) {
  Watchdog dog;
  start(host(chassis_yaml("", 5000)));
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(chassis, msg::kOn).type, msg::kOk);

  // No active pilot: nobody may drive.
  auto r = move(chassis, 0.5);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("no active pilot"), std::string::npos) << r.error_text();

  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 0.5).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx > 0.45; }));
  EXPECT_EQ(newest<ChassisData>(chassis).active_pilot, tool().component().raw());

  // Another pilot takes over: the robot stops, and our MOVEs are refused.
  const Address other = Address::make(0, class_ids::kPilot, 9);
  ASSERT_EQ(claim(chassis, other).type, msg::kOk);
  r = move(chassis, 0.5);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("not the active pilot"), std::string::npos) << r.error_text();
  ASSERT_TRUE(until([&] {
    const auto d = newest<ChassisData>(chassis);
    return d.vx == 0.0 && d.omega == 0.0;
  }));
  const auto d = newest<ChassisData>(chassis);
  EXPECT_EQ(d.active_pilot, other.raw());
  EXPECT_EQ(d.watchdog_stops, 0u) << "it was the pilot change that stopped it";
}

TEST_F(RobotSimTest, WatchdogStopsTheRobotWhenMovesStopTolerant) {
  Watchdog dog;
  start(host(chassis_yaml("", 500)));
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(chassis, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);

  // MOVEs every 20 ms (25x inside the 500 ms watchdog) for 1 s: the robot keeps driving.
  for (int i = 0; i < 50; ++i) {
    ASSERT_EQ(move(chassis, 0.4, 0.1).type, msg::kOk);
    pause(20);
  }
  auto d = newest<ChassisData>(chassis);
  EXPECT_GT(d.vx, 0.3);
  EXPECT_EQ(d.watchdog_stops, 0u);

  // MOVEs stop: within the watchdog time (plus braking) the robot stands, once counted.
  ASSERT_TRUE(until([&] {
    const auto s = newest<ChassisData>(chassis);
    return s.vx == 0.0 && s.omega == 0.0;
  }));
  d = newest<ChassisData>(chassis);
  EXPECT_EQ(d.watchdog_stops, 1u);
  // Standing still is not a watchdog event.
  pause(700);
  EXPECT_EQ(newest<ChassisData>(chassis).watchdog_stops, 1u);
}

// On the virtual clock the watchdog is exact: the first cycle more than watchdog_ms
// after the last MOVE stops the robot, not one before.
TEST_F(RobotSimTest, WatchdogStopsTheRobotAtTheFirstCycleAfterWatchdogMs) {
  Watchdog dog;
  start(host(chassis_yaml("", 500)));  // a 10 ms period: cycles at +10, +20, ... ms
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(chassis, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 0.4).type, msg::kOk);  // at +0 ms
  pause(500);
  auto d = newest<ChassisData>(chassis);
  EXPECT_GT(d.vx, 0.0);
  EXPECT_EQ(d.watchdog_stops, 0u) << "500 ms after the MOVE is not more than watchdog_ms";
  pause(10);
  d = newest<ChassisData>(chassis);
  EXPECT_EQ(d.watchdog_stops, 1u) << "the cycle at +510 ms";
  EXPECT_LT(d.vx, 0.4) << "braking";
}

TEST_F(RobotSimTest, ChassisRejectsMalformedMovesAndReportsItsParameters) {
  Watchdog dog;
  start(host(chassis_yaml(", vx_max: 0.7, boundary_front: 0.4, safety_margin: 0.2", 2500)));
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(chassis, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  const double bad[2] = {1.0, 2.0};  // two doubles, not three
  EXPECT_EQ(h().call(chassis, interfaces::kChassisMove, bad, sizeof bad).type, msg::kError);
  EXPECT_EQ(move(chassis, std::nan("")).type, msg::kError);
  EXPECT_EQ(h().stats(chassis).malformed, 2u);

  const auto r = h().call(chassis, interfaces::kChassisGetParams);
  ASSERT_EQ(r.type, interfaces::kChassisParamsReply);
  interfaces::ChassisParams p;
  ASSERT_EQ(r.body.size(), sizeof p);
  std::memcpy(&p, r.body.data(), sizeof p);
  EXPECT_DOUBLE_EQ(p.vx_max, 0.7);
  EXPECT_DOUBLE_EQ(p.boundary_front, 0.4);
  EXPECT_DOUBLE_EQ(p.safety_margin, 0.2);
  EXPECT_EQ(p.watchdog_ns, 2500 * rt::kNsPerMs);

  // Commands beyond the limits are clamped.
  ASSERT_EQ(move(chassis, 5.0).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx > 0.69; }));
  EXPECT_LE(newest<ChassisData>(chassis).vx, 0.7 + 1e-9);
}

TEST_F(RobotSimTest, ChassisStopsAtWallsOfTheMapTolerant) {
  Watchdog dog;
  // In the corridor (y 6..10) at y = 8, facing north: the wall at y = 10 (9.95 ..
  // 10.05) is 1.95 m ahead of the reference point, 1.65 m ahead of the front.
  start(host(chassis_yaml(", map: \"" + kOffice + "\", initial_x: 7.5, initial_y: 8.0, initial_phi: 1.5707963", 5000)));
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(chassis, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 1.0).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).collisions > 0; }));
  const auto d = newest<ChassisData>(chassis);
  EXPECT_EQ(d.vx, 0.0);
  // The front (0.3 m ahead) stops short of the wall's first cell (9.90), never
  // beyond; by at most one step (0.01 m, or 0.1 m after a 10-period overrun).
  EXPECT_GT(d.truth_y + 0.3, 9.75);
  EXPECT_LT(d.truth_y + 0.3, 10.0);
}

// ---------------------------------------------------------------- Odometry and Position

TEST_F(RobotSimTest, OdometryIntegratesTheIncrementsAndResets) {
  Watchdog dog;
  // Equal ramps for vx and omega keep their ratio, so the robot drives a true circle.
  start(host(chassis_yaml(", acc_max: 1.0, dec_max: 1.0, omega_acc_max: 1.0", 5000) + odometry_position_yaml()));
  const Address chassis = h().address_of("chassis");
  const Address odometry = h().address_of("odometry");
  ASSERT_EQ(h().call(odometry, msg::kOn).type, msg::kOk);  // switches the chassis on
  ASSERT_EQ(h().status(chassis), msg::kEnabled);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 0.5, 0.5).type, msg::kOk);  // an arc of radius 1 m
  pause(800);
  ASSERT_EQ(move(chassis, 0.0, 0.0).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx == 0.0; }));
  pause(50);
  const auto c = newest<ChassisData>(chassis);
  const auto o = newest<OdometryData>(odometry);
  // Without noise the odometry is the true motion from the start pose (0, 0, 0).
  EXPECT_NEAR(o.x, c.truth_x, 1e-6);
  EXPECT_NEAR(o.y, c.truth_y, 1e-6);
  EXPECT_NEAR(o.phi, c.truth_phi, 1e-6);
  EXPECT_GT(o.phi, 0.2);
  // On the arc of radius 1: x = sin(phi), y = 1 - cos(phi), distance = phi.
  EXPECT_NEAR(o.x, std::sin(o.phi), 1e-6);
  EXPECT_NEAR(o.y, 1.0 - std::cos(o.phi), 1e-6);
  EXPECT_NEAR(o.distance, o.phi, 1e-6);

  ASSERT_EQ(h().call(odometry, interfaces::kOdometryReset).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<OdometryData>(odometry).resets == 1; }));
  const auto z = newest<OdometryData>(odometry);
  EXPECT_EQ(z.x, 0.0);
  EXPECT_EQ(z.y, 0.0);
  EXPECT_EQ(z.distance, 0.0);
}

TEST_F(RobotSimTest, PositionUpdateUsesTheOdometryAtTheUpdatesTimeTolerant) {
  Watchdog dog;
  start(host(chassis_yaml("", 5000) + odometry_position_yaml(", initial_x: 1.0, initial_y: 2.0")));
  const Address chassis = h().address_of("chassis");
  const Address odometry = h().address_of("odometry");
  const Address position = h().address_of("position");
  ASSERT_EQ(h().call(position, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  // Before any UPDATE: the initial pose carried by the odometry.
  const auto p0 = newest<PositionData>(position);
  EXPECT_NEAR(p0.x, 1.0, 1e-9);
  EXPECT_NEAR(p0.y, 2.0, 1e-9);
  EXPECT_EQ(p0.updates, 0u);

  // Drive straight at 0.5 m/s; remember an odometry sample half-way.
  ASSERT_EQ(move(chassis, 0.5).type, msg::kOk);
  pause(500);
  wire::SampleHeader mid_header;
  const auto mid = newest<OdometryData>(odometry, &mid_header);
  pause(600);
  ASSERT_EQ(move(chassis, 0.0).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx == 0.0; }));
  pause(50);
  const auto now = newest<OdometryData>(odometry);
  const double since = now.x - mid.x;  // driven after the update's time
  ASSERT_GT(since, 0.2) << "the test needs motion after the update's time";

  // UPDATE for the half-way moment: facing north at (10, 5).
  interfaces::PositionUpdate u;
  u.time_ns = mid_header.time_ns;
  u.x = 10.0;
  u.y = 5.0;
  u.phi = std::numbers::pi / 2;
  u.var_x = u.var_y = 0.04;
  u.var_phi = 0.01;
  const auto r = h().call_with(position, interfaces::kPositionUpdate, u);
  ASSERT_EQ(r.type, msg::kOk) << r.error_text();
  // Standing still now, the pose is the update moved on by what was driven since then
  // (north, in the updated frame), not the update itself.
  const auto p = newer_than<PositionData>(position, mid_header.time_ns + 1);
  ASSERT_TRUE(until([&] { return newest<PositionData>(position).updates == 1; }));
  const auto q = newest<PositionData>(position);
  EXPECT_NEAR(q.x, 10.0, 1e-3);
  EXPECT_NEAR(q.y, 5.0 + since, 1e-3) << "the odometry at the update's time must be used, not now's";
  EXPECT_NEAR(q.phi, std::numbers::pi / 2, 1e-6);
  EXPECT_EQ(q.reference_time_ns, mid_header.time_ns);
  EXPECT_GE(q.var_x, 0.04);
  (void)p;

  // A time before the odometry's history: refused with the reason.
  u.time_ns = mid_header.time_ns - 3600 * rt::kNsPerSec;
  const auto old = h().call_with(position, interfaces::kPositionUpdate, u);
  EXPECT_EQ(old.type, msg::kError);
  EXPECT_NE(old.error_text().find("no odometry"), std::string::npos) << old.error_text();
  // Malformed: counted.
  u.time_ns = mid_header.time_ns;
  u.x = std::nan("");
  EXPECT_EQ(h().call_with(position, interfaces::kPositionUpdate, u).type, msg::kError);
  EXPECT_EQ(h().stats(position).malformed, 1u);
}

TEST_F(RobotSimTest, PositionSwitchedOnAgainContinuesFromItsLastPose) {
  Watchdog dog;
  start(host(chassis_yaml("", 5000) + odometry_position_yaml(", initial_x: 1.0, initial_y: 2.0")));
  const Address chassis = h().address_of("chassis");
  const Address odometry = h().address_of("odometry");
  const Address position = h().address_of("position");
  ASSERT_EQ(h().call(position, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 0.5).type, msg::kOk);
  pause(600);
  ASSERT_EQ(move(chassis, 0.0).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx == 0.0; }));
  pause(50);
  wire::SampleHeader before_header;
  const auto before = newest<PositionData>(position, &before_header);
  ASSERT_GT(before.x, 1.1);
  // The odometry goes away (the position follows it into ERROR) and comes back at zero.
  ASSERT_EQ(h().call(odometry, msg::kOff).type, msg::kOk);
  ASSERT_TRUE(until([&] { return h().status(position) == msg::kError; }));
  ASSERT_EQ(h().call(position, msg::kOn).type, msg::kOk);
  // Samples made after the restart (the rings still hold the old ones).
  const auto after = newer_than<PositionData>(position, before_header.time_ns);
  EXPECT_NEAR(newer_than<OdometryData>(odometry, before_header.time_ns).x, 0.0, 1e-9)
      << "the odometry started again at zero";
  EXPECT_NEAR(after.x, before.x, 1e-6) << "not back at initial_x";
  EXPECT_NEAR(after.y, before.y, 1e-6);
}

TEST_F(RobotSimTest, OdometryResetDoesNotMoveThePositionTolerant) {
  Watchdog dog;
  start(host(chassis_yaml("", 5000) + odometry_position_yaml(", initial_x: 1.0, initial_y: 2.0")));
  const Address chassis = h().address_of("chassis");
  const Address odometry = h().address_of("odometry");
  const Address position = h().address_of("position");
  ASSERT_EQ(h().call(position, msg::kOn).type, msg::kOk);
  // Anchored (initial pose at its first odometry sample) before the robot moves.
  ASSERT_NEAR(newest<PositionData>(position).x, 1.0, 1e-9);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 0.5).type, msg::kOk);
  pause(500);
  ASSERT_EQ(h().call(odometry, interfaces::kOdometryReset).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<OdometryData>(odometry).resets == 1; }));
  pause(300);
  ASSERT_EQ(move(chassis, 0.0).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx == 0.0; }));
  pause(50);
  // The odometry restarted near zero; the position kept counting from (1, 2).
  const auto c = newest<ChassisData>(chassis);
  const auto p = newest<PositionData>(position);
  EXPECT_LT(newest<OdometryData>(odometry).x, c.truth_x - 0.1);
  EXPECT_NEAR(p.x, 1.0 + c.truth_x, 1e-6);
  EXPECT_NEAR(p.y, 2.0 + c.truth_y, 1e-6);
}

// ---------------------------------------------------------------- Scan2D

interfaces::LadarData make_ladar(std::initializer_list<float> ranges, float start, float step) {
  interfaces::LadarData l;
  l.max_range = 10.0F;
  l.min_range = 0.0F;
  l.start_angle = start;
  l.angle_step = step;
  l.beam_count = 0;
  for (float r : ranges) l.range[l.beam_count++] = r;
  return l;
}

TEST(Scan2dGeometry, AppliesTheMountingOffsetInTheRobotFrame) {
  // Three beams: -90, 0, +90 degrees in the sensor frame.
  const float q = static_cast<float>(std::numbers::pi / 2);
  const auto ladar = make_ladar({1.0F, 2.0F, 3.0F}, -q, q);
  components::Scan2d::Geometry g;
  g.mount_x = 0.2;
  g.mount_y = 0.1;
  g.mount_phi = std::numbers::pi / 2;  // the sensor looks left
  interfaces::Scan2dData s;
  components::Scan2d::convert(ladar, g, s);
  ASSERT_EQ(s.point_count, 3u);
  // Beam -90 in a sensor that looks left points forward: (0.2 + 1, 0.1).
  EXPECT_NEAR(s.x[0], 1.2, 1e-6);
  EXPECT_NEAR(s.y[0], 0.1, 1e-6);
  // Beam 0: left, 2 m.
  EXPECT_NEAR(s.x[1], 0.2, 1e-6);
  EXPECT_NEAR(s.y[1], 2.1, 1e-6);
  // Beam +90: backwards, 3 m.
  EXPECT_NEAR(s.x[2], -2.8, 1e-6);
  EXPECT_NEAR(s.y[2], 0.1, 1e-6);
  EXPECT_NEAR(s.range[1], 2.0, 1e-6);
  EXPECT_NEAR(s.bearing[2], q, 1e-6);
  for (uint32_t i = 0; i < 3; ++i) EXPECT_EQ(s.type[i], interfaces::kScanPointNormal);
}

TEST(Scan2dGeometry, RangeWindowAndNoEchoBeams) {
  const auto ladar = make_ladar({0.02F, 0.0F, 5.0F, 9.0F, -1.0F}, 0.0F, 0.1F);
  components::Scan2d::Geometry g;
  g.range_min = 0.05;
  g.range_max = 8.0;  // 9 m counts as no echo
  interfaces::Scan2dData s;
  components::Scan2d::convert(ladar, g, s);
  // 0.02: too close, dropped. 0, 9, -1: no echo -> max-range points at 8 m.
  ASSERT_EQ(s.point_count, 4u);
  EXPECT_EQ(s.type[0], interfaces::kScanPointMaxRange);
  EXPECT_NEAR(s.range[0], 8.0, 1e-6);
  EXPECT_EQ(s.type[1], interfaces::kScanPointNormal);
  EXPECT_NEAR(s.range[1], 5.0, 1e-6);
  EXPECT_EQ(s.type[2], interfaces::kScanPointMaxRange);
  EXPECT_EQ(s.type[3], interfaces::kScanPointMaxRange);
  EXPECT_FLOAT_EQ(s.max_range, 8.0F);
  g.keep_max_range = false;
  components::Scan2d::convert(ladar, g, s);
  ASSERT_EQ(s.point_count, 1u);
  EXPECT_NEAR(s.range[0], 5.0, 1e-6);
}

TEST(Scan2dGeometry, MedianFilterRemovesASingleBeamSpike) {
  const auto ladar = make_ladar({2.0F, 2.0F, 0.3F, 2.0F, 2.0F}, 0.0F, 0.01F);
  components::Scan2d::Geometry g;
  g.median = 3;
  interfaces::Scan2dData s;
  components::Scan2d::convert(ladar, g, s);
  ASSERT_EQ(s.point_count, 5u);
  for (uint32_t i = 0; i < 5; ++i) EXPECT_NEAR(s.range[i], 2.0, 1e-6) << i;
  g.median = 1;  // off: the spike stays
  components::Scan2d::convert(ladar, g, s);
  EXPECT_NEAR(s.range[2], 0.3, 1e-6);
}

// ---------------------------------------------------------------- LadarSim

TEST_F(RobotSimTest, LadarSimRangesMatchTheKnownWallsOfTheMap) {
  Watchdog dog;
  // At (7.5, 8) facing east in the corridor: walls at y = 10 (9.95 .. 10.05) and
  // y = 6 (5.95 .. 6.05), the east wall at x = 24 (23.95 ..), no doors near x = 7.5.
  // The sensor sits 0.2 m ahead of the reference point.
  start(host(chassis_yaml(", initial_x: 7.5, initial_y: 8.0", 5000) + odometry_position_yaml() +
             ladar_scan_yaml(kOffice, ", mount_x: 0.2", ", mount_x: 0.2")));
  auto loaded = maps::load_map(kOffice);
  ASSERT_TRUE(loaded.ok()) << loaded.error_text();
  const Address ladar = h().address_of("ladar");
  const Address scan2d = h().address_of("scan2d");
  ASSERT_EQ(h().call(scan2d, msg::kOn).type, msg::kOk);  // -> ladar -> chassis, odometry
  const auto l = newest<interfaces::LadarData>(ladar);
  ASSERT_EQ(l.beam_count, 541u);
  const double step = static_cast<double>(l.angle_step);
  EXPECT_NEAR(step, 0.5 * std::numbers::pi / 180.0, 1e-6);
  const auto beam = [&](double deg) {
    const double a = deg * std::numbers::pi / 180.0 - static_cast<double>(l.start_angle);
    return static_cast<std::size_t>(std::lround(a / step));
  };
  // Against the walls as drawn (within two map cells: the drawing rounds to cells),
  // and exactly against the map's own ray caster from the sensor's pose.
  const double cell = 0.05;
  const auto cast = [&](double deg) {
    return static_cast<double>(loaded.map->cast_ray(7.7, 8.0, deg * std::numbers::pi / 180.0, 20.0).range);
  };
  EXPECT_NEAR(l.range[beam(90)], 9.95 - 8.0, 2 * cell);                  // north wall
  EXPECT_NEAR(l.range[beam(-90)], 8.0 - 6.05, 2 * cell);                 // south wall
  EXPECT_NEAR(l.range[beam(0)], 23.95 - 7.7, 2 * cell);                  // east end of the corridor
  EXPECT_NEAR(l.range[beam(45)], 1.95 * std::numbers::sqrt2, 3 * cell);  // north wall, diagonally
  for (double deg : {90.0, -90.0, 0.0, 45.0, -30.0, 120.0}) {
    EXPECT_NEAR(l.range[beam(deg)], cast(deg), 1e-4) << deg << " degrees";
  }

  // Scan2D puts the north wall 1.95 m to the left of the robot (sensor 0.2 m ahead).
  const auto s = newest<interfaces::Scan2dData>(scan2d);
  ASSERT_EQ(s.point_count, 541u);
  const std::size_t i = beam(90);
  EXPECT_NEAR(s.x[i], 0.2, 1e-3);
  EXPECT_NEAR(s.y[i], l.range[i], 1e-4);
  EXPECT_EQ(s.odometry_valid, 1);
  EXPECT_NEAR(s.odometry_x, 0.0, 1e-6);  // standing: the odometry is still at its origin
}

TEST_F(RobotSimTest, ScansCarryTheOdometryOfTheirOwnTimeWhileDrivingTolerant) {
  Watchdog dog;
  start(host(chassis_yaml(", initial_x: 5.0, initial_y: 8.0", 5000) + odometry_position_yaml() +
             ladar_scan_yaml(kOffice)));
  const Address chassis = h().address_of("chassis");
  const Address scan2d = h().address_of("scan2d");
  ASSERT_EQ(h().call(scan2d, msg::kOn).type, msg::kOk);
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_EQ(move(chassis, 0.8, 0.2).type, msg::kOk);
  pause(700);  // up to speed
  // Each scan's odometry is the motion up to the scan's own time: without noise it
  // equals the true pose at that time relative to the start. A scan paired with the
  // odometry of another moment would be off by 0.8 m/s x the time difference.
  int checked = 0;
  int64_t last = 0;
  for (int i = 0; i < 5; ++i) {
    wire::SampleHeader sh;
    const auto s = newer_than<interfaces::Scan2dData>(scan2d, last, &sh);
    last = sh.time_ns;
    ASSERT_EQ(s.odometry_valid, 1);
    wire::SampleHeader ch;
    ChassisData c;
    ASSERT_TRUE(h().get_data(chassis, ch, c, sh.time_ns));
    ASSERT_EQ(ch.time_ns, sh.time_ns) << "LadarSim stamps a scan with the chassis sample it rendered";
    const Pose2d rel = components::between(Pose2d{5.0, 8.0, 0.0}, Pose2d{c.truth_x, c.truth_y, c.truth_phi});
    EXPECT_NEAR(s.odometry_x, rel.x, 1e-6);
    EXPECT_NEAR(s.odometry_y, rel.y, 1e-6);
    EXPECT_NEAR(s.odometry_phi, rel.phi, 1e-6);
    ++checked;
  }
  EXPECT_EQ(checked, 5);
  ASSERT_EQ(move(chassis, 0.0).type, msg::kOk);
}

TEST_F(RobotSimTest, MissingMapPutsOnlyTheLadarInErrorWithTheFileName) {
  Watchdog dog;
  start(host(chassis_yaml("", 5000) + odometry_position_yaml() + ladar_scan_yaml("/nonexistent/nowhere.yaml") +
             R"(  - name: gen
    class: Generator
    instance: 0
    data_task: {period_ms: 10}
)"));
  const Address ladar = h().address_of("ladar");
  const auto r = h().call(ladar, msg::kOn);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("/nonexistent/nowhere.yaml"), std::string::npos) << r.error_text();
  EXPECT_NE(h().log().find("nowhere.yaml"), std::string::npos) << h().log();
  EXPECT_EQ(h().status(ladar), msg::kError);
  // Scan2D depends on it: its ON fails, it does not crash.
  EXPECT_EQ(h().call(h().address_of("scan2d"), msg::kOn).type, msg::kError);
  // Everything else runs.
  const Address gen = h().address_of("gen");
  ASSERT_EQ(h().call(gen, msg::kOn).type, msg::kOk);
  ASSERT_EQ(h().call(h().address_of("position"), msg::kOn).type, msg::kOk);
  wire::SampleHeader sh;
  interfaces::GeneratorData g;
  EXPECT_TRUE(until([&] { return h().get_data(gen, sh, g) && g.counter > 3; }));
  EXPECT_EQ(h().status(h().address_of("chassis")), msg::kEnabled);
}

TEST_F(RobotSimTest, MalformedMapGivesFileAndLine) {
  Watchdog dog;
  const auto dir = std::filesystem::temp_directory_path() / ("rack_map_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto yaml = dir / "broken.yaml";
  {
    std::ofstream f(yaml);
    f << "image: broken.pgm\nresolution: 0.05\norigin: [0.0, 0.0]\nnegate: 0\n"
         "occupied_thresh: 0.65\nfree_thresh: 0.196\n";  // origin needs three numbers
  }
  start(host(chassis_yaml("", 5000) + odometry_position_yaml() + ladar_scan_yaml(yaml.string())));
  const auto r = h().call(h().address_of("ladar"), msg::kOn);
  std::filesystem::remove_all(dir);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("broken.yaml:3"), std::string::npos) << r.error_text();
  EXPECT_EQ(h().call(h().address_of("position"), msg::kOn).type, msg::kOk);
}

// ---------------------------------------------------------------- Path

TEST(PathMaking, ParsesWaypointsAndNamesTheBadItem) {
  interfaces::PathMake w;
  int item = 0;
  EXPECT_EQ(components::Path::parse_waypoints(" 1,2; 3.5 ,-4;5e-1,6; ", w, item), nullptr);
  ASSERT_EQ(w.count, 3u);
  EXPECT_DOUBLE_EQ(w.x[1], 3.5);
  EXPECT_DOUBLE_EQ(w.y[1], -4.0);
  EXPECT_DOUBLE_EQ(w.x[2], 0.5);
  const char* why = components::Path::parse_waypoints("1,2; 3;4", w, item);
  ASSERT_NE(why, nullptr);
  EXPECT_EQ(item, 2);
  EXPECT_NE(std::string(why).find("','"), std::string::npos) << why;
  EXPECT_NE(components::Path::parse_waypoints("", w, item), nullptr);
  EXPECT_NE(components::Path::parse_waypoints("1,x", w, item), nullptr);
}

TEST(PathMaking, TheSplinePassesThroughEveryWaypoint) {
  interfaces::PathMake w;
  int item = 0;
  ASSERT_EQ(components::Path::parse_waypoints("0,0; 4,0; 4,3; 0,3", w, item), nullptr);
  interfaces::PathData open;
  ASSERT_EQ(components::Path::make_path(w, 0.1, open), nullptr);
  interfaces::PathData loop;
  w.closed = 1;
  ASSERT_EQ(components::Path::make_path(w, 0.1, loop), nullptr);
  for (const auto* p : {&open, &loop}) {
    for (uint32_t k = 0; k < w.count; ++k) {
      double best = 1e9;
      for (uint32_t i = 0; i < p->point_count; ++i) {
        best = std::min(best, std::hypot(p->x[i] - w.x[k], p->y[i] - w.y[k]));
      }
      EXPECT_LT(best, 1e-4) << "waypoint " << k;
    }
    // Samples about `resolution` apart.
    for (uint32_t i = 1; i < p->point_count; ++i) {
      EXPECT_LT(std::hypot(p->x[i] - p->x[i - 1], p->y[i] - p->y[i - 1]), 0.15) << i;
    }
  }
  // The polyline is 4 + 3 + 4 = 11 m (open) and 14 m closed; a smooth curve is a bit longer.
  EXPECT_GT(open.length, 11.0);
  EXPECT_LT(open.length, 12.5);
  EXPECT_GT(loop.length, 14.0);
  EXPECT_LT(loop.length, 16.0);
  EXPECT_EQ(open.x[open.point_count - 1], 0.0F);
  EXPECT_EQ(open.y[open.point_count - 1], 3.0F);
  EXPECT_EQ(loop.closed, 1);
  // Two equal neighbours, or too many points, are refused.
  w.x[1] = w.x[0];
  w.y[1] = w.y[0];
  EXPECT_NE(components::Path::make_path(w, 0.1, open), nullptr);
  ASSERT_EQ(components::Path::parse_waypoints("0,0; 1000,0", w, item), nullptr);
  EXPECT_NE(components::Path::make_path(w, 0.1, open), nullptr);
  // A chord far beyond any step count (it overflowed the count's conversion: UB).
  ASSERT_EQ(components::Path::parse_waypoints("0,0; 1e35,0", w, item), nullptr);
  EXPECT_NE(components::Path::make_path(w, 0.1, open), nullptr);
  ASSERT_EQ(components::Path::parse_waypoints("0,0; 1e308,1e308", w, item), nullptr);
  EXPECT_NE(components::Path::make_path(w, 0.1, open), nullptr);
}

TEST_F(RobotSimTest, PathPublishesOnMakeAndRejectsMalformedWaypoints) {
  Watchdog dog;
  start(host(R"(  - name: path
    class: Path
    instance: 0
    data_task: {period_ms: 20, ring: 4}
    params: {waypoints: "0,0; 2,0; 2,2"}
)"));
  const Address path = h().address_of("path");
  ASSERT_EQ(h().call(path, msg::kOn).type, msg::kOk);
  auto p = newest<interfaces::PathData>(path);
  EXPECT_EQ(p.waypoint_count, 3u);
  EXPECT_EQ(p.makes, 1u);

  interfaces::PathMake m;
  m.count = 2;
  m.x[1] = 5.0;
  ASSERT_EQ(h().call_with(path, interfaces::kPathMake, m).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<interfaces::PathData>(path).makes == 2; }));
  p = newest<interfaces::PathData>(path);
  EXPECT_EQ(p.waypoint_count, 2u);
  EXPECT_NEAR(p.length, 5.0, 1e-3);

  m.count = 1;
  const auto r = h().call_with(path, interfaces::kPathMake, m);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("at least 2"), std::string::npos) << r.error_text();

  // A malformed parameter text is refused where it is set (the Path's rule, the same
  // the host file and init() apply): the reason in the answer, the previous path kept.
  const auto bad = h().set_param(path, "waypoints", wire::ParamKind::kString, 0, 0.0, "1,1; oops");
  EXPECT_EQ(bad.type, msg::kError);
  EXPECT_NE(bad.error_text().find("waypoints: item 2"), std::string::npos) << bad.error_text();
  p = newest<interfaces::PathData>(path);
  EXPECT_EQ(p.makes, 2u);
  EXPECT_EQ(p.waypoint_count, 2u);
}

TEST(PathConfig, MalformedWaypointsInTheHostFileNameTheParameter) {
  // The Path's rule (check_parameters) runs in the loader: the host file is refused
  // at the parameter's line, before anything starts (it was an ERROR at ON).
  ComponentRegistry registry;
  components::register_builtin(registry);
  const auto r = load_host_text(host(R"(  - name: path
    class: Path
    instance: 0
    data_task: {period_ms: 20}
    params: {waypoints: "0,0; 2;0"}
)"),
                                "test.yaml", registry, rt::probe_capabilities());
  EXPECT_EQ(r.host, nullptr);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].line, 8);
  EXPECT_NE(r.errors[0].message.find("parameter 'waypoints': item 2"), std::string::npos) << r.errors[0].str();
}

// ---------------------------------------------------------------- Pilot

TEST(PilotClearance, MeasuresFreeSpaceAheadOfTheOutline) {
  interfaces::Scan2dData s;
  s.max_range = 20.0F;
  const auto add = [&](float x, float y, uint8_t type = interfaces::kScanPointNormal) {
    s.x[s.point_count] = x;
    s.y[s.point_count] = y;
    s.type[s.point_count] = type;
    ++s.point_count;
  };
  components::Pilot::Outline o{0.3, 0.3, 0.25, 0.25, 0.1};
  add(2.0F, 1.0F);   // ahead but beside the corridor (|y| > 0.35)
  add(-2.0F, 0.0F);  // behind
  add(1.5F, 0.0F, interfaces::kScanPointMaxRange);
  auto c = components::Pilot::clearance(s, o);
  EXPECT_FALSE(c.inside);
  EXPECT_FLOAT_EQ(static_cast<float>(c.free_ahead), 20.0F);
  add(1.3F, 0.3F);  // in the corridor, 1.0 m ahead of the front
  c = components::Pilot::clearance(s, o);
  EXPECT_NEAR(c.free_ahead, 1.0, 1e-6);
  EXPECT_FALSE(c.inside);
  add(0.35F, -0.1F);  // inside the safety margin
  c = components::Pilot::clearance(s, o);
  EXPECT_TRUE(c.inside);
  EXPECT_TRUE(c.turn_blocked);
}

// The whole simulated robot: chassis (stopping at walls), ladar, odometry, scan2d,
// position and a pilot, on the office map.
std::string robot_yaml(double x, double y, double phi, const std::string& pilot_params) {
  char pose[160];
  std::snprintf(pose, sizeof pose, ", map: \"%s\", initial_x: %.3f, initial_y: %.3f, initial_phi: %.4f",
                kOffice.c_str(), x, y, phi);
  char ppose[120];
  std::snprintf(ppose, sizeof ppose, ", initial_x: %.3f, initial_y: %.3f, initial_phi: %.4f", x, y, phi);
  return host(chassis_yaml(pose, 300) + odometry_position_yaml(ppose) + ladar_scan_yaml(kOffice, ", mount_x: 0.2") +
              R"(  - name: pilot
    class: Pilot
    instance: 0
    data_task: {priority: 40, period_ms: 50}
    params: {chassis: chassis, position: position, scan2d: scan2d, vx_max: 1.0)" +
              // mode: hold unless the caller gives one (a key twice in a map is refused)
              (pilot_params.find("mode:") == std::string::npos ? ", mode: hold" : "") + pilot_params + "}\n");
}

// Smallest distance from the outline at the true pose to an occupied cell (negative
// when the outline overlaps one), sampled along the outline's edges.
double outline_clearance(const maps::OccupancyMap& map, const ChassisData& d) {
  double best = 1e9;
  const Pose2d pose{d.truth_x, d.truth_y, d.truth_phi};
  for (int k = 0; k < 40; ++k) {
    const double t = k / 40.0;
    const Pose2d corners[] = {
        {0.3 - 0.6 * t, 0.25, 0}, {-0.3, 0.25 - 0.5 * t, 0}, {-0.3 + 0.6 * t, -0.25, 0}, {0.3, -0.25 + 0.5 * t, 0}};
    for (const auto& c : corners) {
      const Pose2d w = components::compose(pose, c);
      for (int a = 0; a < 16; ++a) {
        const double ang = a * std::numbers::pi / 8;
        best = std::min(best, static_cast<double>(map.cast_ray(w.x, w.y, ang, 2.0).range));
      }
    }
  }
  return best;
}

TEST_F(RobotSimTest, PilotReachesADestinationInTheMapWithoutTouchingWallsTolerant) {
  Watchdog dog(std::chrono::seconds(60));
  auto loaded = maps::load_map(kOffice);
  ASSERT_TRUE(loaded.ok()) << loaded.error_text();
  const maps::OccupancyMap& map = *loaded.map;
  // From the corridor's west end, through the door at x 9.0-10.2 (y = 6) into room B.
  start(robot_yaml(3.0, 8.0, 0.0, ""));
  const Address pilot = h().address_of("pilot");
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(pilot, msg::kOn).type, msg::kOk);  // switches on the whole robot
  EXPECT_EQ(newest<ChassisData>(chassis).active_pilot, pilot.raw());
  // Two legs: along the corridor to in front of the door, then through it.
  interfaces::PilotDestination dest{9.6, 7.8};
  ASSERT_EQ(h().call_with(pilot, interfaces::kPilotSetDestination, dest).type, msg::kOk);
  double min_clearance = 1e9;
  const auto drive_until_reached = [&] {
    return until(
        [&] {
          min_clearance = std::min(min_clearance, outline_clearance(map, newest<ChassisData>(chassis)));
          const auto p = newest<PilotData>(pilot);
          // Reached, for this destination (not still the previous one's status).
          return p.status == static_cast<uint8_t>(interfaces::PilotStatus::kReached) && p.target_x == dest.x &&
                 p.target_y == dest.y;
        },
        std::chrono::milliseconds(25000));
  };
  ASSERT_TRUE(drive_until_reached()) << "pilot status " << int(newest<PilotData>(pilot).status);
  dest = {9.6, 4.5};
  ASSERT_EQ(h().call_with(pilot, interfaces::kPilotSetDestination, dest).type, msg::kOk);
  ASSERT_TRUE(drive_until_reached()) << "pilot status " << int(newest<PilotData>(pilot).status);
  const auto c = newest<ChassisData>(chassis);
  // Odometry without noise: position and truth agree; tolerance is the pilot's plus braking.
  EXPECT_NEAR(c.truth_x, 9.6, 0.3);
  EXPECT_NEAR(c.truth_y, 4.5, 0.3);
  EXPECT_EQ(c.collisions, 0u);
  EXPECT_GT(min_clearance, 0.0) << "the outline touched a wall";
  EXPECT_EQ(newest<PilotData>(pilot).moves_refused, 0u);
  // OFF stops the robot and releases the chassis.
  ASSERT_EQ(h().call(pilot, msg::kOff).type, msg::kOk);
  ASSERT_TRUE(until([&] {
    const auto d = newest<ChassisData>(chassis);
    return d.vx == 0.0 && d.active_pilot == 0;
  }));
}

TEST_F(RobotSimTest, PilotStopsBeforeAnObstacleInItsWayTolerant) {
  Watchdog dog(std::chrono::seconds(60));
  // Facing south in the corridor at x = 7.5 (no door): the destination lies beyond the
  // wall at y = 6, so the straight line runs into it. The pilot must stop in front.
  start(robot_yaml(7.5, 8.5, -std::numbers::pi / 2, ""));
  const Address pilot = h().address_of("pilot");
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(pilot, msg::kOn).type, msg::kOk);
  const interfaces::PilotDestination dest{7.5, 3.0};
  ASSERT_EQ(h().call_with(pilot, interfaces::kPilotSetDestination, dest).type, msg::kOk);
  ASSERT_TRUE(
      until([&] { return newest<PilotData>(pilot).status == static_cast<uint8_t>(interfaces::PilotStatus::kBlocked); },
            std::chrono::milliseconds(20000)));
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).vx == 0.0; }));
  const auto c = newest<ChassisData>(chassis);
  EXPECT_EQ(c.collisions, 0u);
  // The front (0.3 m ahead of the reference point) stays off the wall (6.05).
  EXPECT_GT(c.truth_y - 0.3, 6.05);
  EXPECT_LT(c.truth_y, 7.5) << "it did drive towards the wall";
  EXPECT_GT(newest<PilotData>(pilot).blocked_cycles, 0u);
}

TEST_F(RobotSimTest, PilotFollowsThePathAndAnotherPilotPreemptsIt) {
  Watchdog dog(std::chrono::seconds(60));
  start(robot_yaml(3.0, 8.0, 0.0, ", path: path, mode: path") + R"(  - name: path
    class: Path
    instance: 0
    data_task: {period_ms: 50, ring: 4}
    params: {waypoints: "3,8; 6,8.5; 8,8", closed: false}
)");
  const Address pilot = h().address_of("pilot");
  const Address chassis = h().address_of("chassis");
  ASSERT_EQ(h().call(pilot, msg::kOn).type, msg::kOk);
  ASSERT_TRUE(
      until([&] { return newest<PilotData>(pilot).status == static_cast<uint8_t>(interfaces::PilotStatus::kReached); },
            std::chrono::milliseconds(25000)));
  const auto c = newest<ChassisData>(chassis);
  EXPECT_NEAR(c.truth_x, 8.0, 0.3);
  EXPECT_NEAR(c.truth_y, 8.0, 0.3);
  EXPECT_GT(newest<PilotData>(pilot).path_index, 10u);

  // The tool takes the chassis: the pilot's next MOVE is refused and it stands.
  ASSERT_EQ(claim(chassis, tool()).type, msg::kOk);
  ASSERT_TRUE(until(
      [&] { return newest<PilotData>(pilot).status == static_cast<uint8_t>(interfaces::PilotStatus::kPreempted); }));
  EXPECT_GE(newest<PilotData>(pilot).moves_refused, 1u);
  EXPECT_EQ(newest<ChassisData>(chassis).active_pilot, tool().component().raw());
  // Told where to go again, it takes the chassis back.
  ASSERT_EQ(h().call(pilot, interfaces::kPilotFollowPath).type, msg::kOk);
  ASSERT_TRUE(until([&] { return newest<ChassisData>(chassis).active_pilot == pilot.raw(); }));
}

}  // namespace
}  // namespace rack
