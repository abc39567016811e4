// The MCL component in a real executor: it switches on its Scan2D source (cascading
// ON), localises from its scans, publishes MclData, sends Position UPDATE, takes INIT,
// and a bad map puts it (only it) in ERROR with the file and line.
//
// The executor is stepped (rack/core/stepper.h): the scans come at virtual times and
// the likelihood's compute worker runs its share inside MCL's step, so every run sees
// the same scans and the same estimates. Only the test of the worker's thread runs
// the executor's threads.
//
// The Scan2D source is a test component class (SimScan2d) that drives the scripted
// robot of mcl_sim.h through the office map and publishes real Scan2dData samples with
// the odometry at each scan's time; UpdateRecorder is a Position class that answers
// UPDATE and remembers it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <mutex>

#include "mcl_sim.h"
#include "rack/components/class_ids.h"
#include "rack/core/data_component.h"
#include "mcl/mcl_types.h"
#include "rack/core/stepper.h"
#include "rack/interfaces/robot.h"
#include "rack/maps/occupancy_map.h"
#include "test_support.h"

namespace rack::test {
namespace {

using interfaces::MclData;
using interfaces::PositionUpdate;
using interfaces::Scan2dData;

const std::string kOffice = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";

// Waiting for a condition moves the virtual clock to the first instant it holds, within
// this much of it.
constexpr int64_t kLimit = 60 * rt::kNsPerSec;

// Test code: allocates in loop() (ray casting into vectors); runs at priority 0.
class SimScan2d final : public DataComponent<Scan2dData> {
 public:
  SimScan2d() : DataComponent(DataTaskMode::kPeriodic) {}

  struct Truth {
    int64_t time_ns;
    SimPose pose;
  };
  bool truth_at(int64_t time_ns, SimPose& out) {
    std::lock_guard lock(mutex_);
    for (const auto& t : truth_) {
      if (t.time_ns == time_ns) {
        out = t.pose;
        return true;
      }
    }
    return false;
  }

 protected:
  void init() override {
    auto r = maps::load_map(kOffice);
    if (!r.ok()) throw std::runtime_error(r.error_text());
    map_ = std::make_unique<maps::OccupancyMap>(std::move(*r.map));
    robot_ = std::make_unique<ScriptedRobot>(*map_, SimConfig{}, 7);
    robot_->place({2.0, 8.0, 0.0});
    sample_ = std::make_unique<Scan2dData>();
  }
  HookResult loop() override {
    if (robot_->step_towards(goal_x_, 8.0)) goal_x_ = goal_x_ > 10 ? 2.0 : 20.0;  // back and forth
    const SimScan s = robot_->scan();
    Scan2dData& d = *sample_;
    d.max_range = s.max_range;
    d.point_count = static_cast<uint32_t>(s.xs.size());
    for (std::size_t i = 0; i < s.xs.size(); ++i) {
      d.x[i] = s.xs[i];
      d.y[i] = s.ys[i];
      d.type[i] = interfaces::kScanPointNormal;
    }
    d.odometry_x = robot_->odometry().x;
    d.odometry_y = robot_->odometry().y;
    d.odometry_phi = robot_->odometry().phi;
    d.odometry_valid = 1;
    const int64_t t = rt::host_time_ns();
    {
      std::lock_guard lock(mutex_);
      truth_.push_back({t, robot_->truth()});
    }
    publish(d, t);
    return HookResult::kOk;
  }

 private:
  std::unique_ptr<maps::OccupancyMap> map_;
  std::unique_ptr<ScriptedRobot> robot_;
  std::unique_ptr<Scan2dData> sample_;
  double goal_x_ = 20.0;
  std::mutex mutex_;
  std::vector<Truth> truth_;
};

class UpdateRecorder final : public Component {
 public:
  int updates() {
    std::lock_guard lock(mutex_);
    return count_;
  }
  PositionUpdate last() {
    std::lock_guard lock(mutex_);
    return last_;
  }

 protected:
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override {
    if (request.type != interfaces::kPositionUpdate) return CommandResult::kUnknown;
    PositionUpdate u;
    if (!wire::read_payload(body, tims::body_is_native(request), u)) {
      reject_malformed(request, "UPDATE: wrong size");
      return CommandResult::kHandled;
    }
    {
      std::lock_guard lock(mutex_);
      ++count_;
      last_ = u;
    }
    reply(request, tims::msg::kOk);
    return CommandResult::kHandled;
  }

 private:
  std::mutex mutex_;
  int count_ = 0;
  PositionUpdate last_{};
};

void register_test_classes(ComponentRegistry& r) {
  r.add(
      {"SimScan2d", class_ids::kScan2d, "test: scripted robot's scans", [] { return std::make_unique<SimScan2d>(); }});
  r.add({"UpdateRecorder", class_ids::kPosition, "test: records Position UPDATEs",
         [] { return std::make_unique<UpdateRecorder>(); }});
}

std::string host_yaml(const std::string& map, const std::string& extra_params = "") {
  return R"(lcm: false
components:
  - name: scans
    class: SimScan2d
    data_task: {priority: 0, period_ms: 20}
  - name: position
    class: UpdateRecorder
  - name: mcl
    class: MCL
    autostart: true
    data_task: {priority: 0}
    params:
      silence_ms: 2000
      map: )" +
         map + R"(
      scan2d: scans
      position: position
      initial_pose: "2.05 7.95 0.02"
      particles_max: 1000
      seed: 5
)" + extra_params +
         R"(
  - name: gen
    class: Generator
    autostart: true
    data_task: {period_ms: 10}
)";
}

TEST(MclComponentTest, LocalisesFromScan2dPublishesAndUpdatesPosition) {
  Watchdog watchdog(std::chrono::seconds(60));
  HostUnderTest host(host_yaml(kOffice), register_test_classes, false, Stepping::kStepped);
  Stepper& s = host.stepper();
  const tims::Address mcl = host.address_of("mcl");
  ASSERT_EQ(host.status(mcl), tims::msg::kEnabled) << host.log();         // autostart: served at start()
  EXPECT_EQ(host.status(host.address_of("scans")), tims::msg::kEnabled);  // cascading ON
  auto* sim = dynamic_cast<SimScan2d*>(host.executor().find("scans"));
  auto* position = dynamic_cast<UpdateRecorder*>(host.executor().find("position"));
  ASSERT_NE(sim, nullptr);
  ASSERT_NE(position, nullptr);

  wire::SampleHeader sh{};
  auto data = std::make_unique<MclData>();
  ASSERT_TRUE(s.run_until([&] { return host.get_data(mcl, sh, *data) && data->updates >= 15; }, kLimit))
      << "MCL did not update: " << host.log();
  SimPose truth;
  ASSERT_TRUE(sim->truth_at(data->scan_time_ns, truth)) << "MclData.scan_time_ns is not a scan's time";
  EXPECT_EQ(sh.time_ns, data->scan_time_ns);
  EXPECT_LT(std::hypot(data->x - truth.x, data->y - truth.y), 0.15);
  EXPECT_GT(data->particle_count, 0U);
  EXPECT_GT(data->shown, 0U);
  EXPECT_LE(data->shown, 100U);  // show_particles default
  EXPECT_GT(data->covariance[0], 0.0);
  EXPECT_GT(data->fit, 0.5F);

  ASSERT_TRUE(s.run_until([&] { return position->updates() > 3; }, kLimit)) << "no Position UPDATE";
  const PositionUpdate u = position->last();
  SimPose at_update;
  ASSERT_TRUE(sim->truth_at(u.time_ns, at_update)) << "UPDATE's time is not a scan's time";
  EXPECT_LT(std::hypot(u.x - at_update.x, u.y - at_update.y), 0.15);
  EXPECT_GT(u.var_x, 0.0);

  // INIT: global re-initialisation is accepted; a malformed body is not.
  interfaces::MclInit init;
  init.global = 1;
  EXPECT_EQ(host.call_with(mcl, interfaces::kMclInit, init).type, tims::msg::kOk);
  EXPECT_EQ(host.call(mcl, interfaces::kMclInit, &init, 8).type, tims::msg::kError);
  EXPECT_EQ(host.status(mcl), tims::msg::kEnabled);
  ASSERT_TRUE(s.run_until([&] { return host.get_data(mcl, sh, *data) && data->updates <= 2; }, kLimit))
      << "INIT did not restart the filter";
}

// The likelihood's second thread (threads 2) is the executor's compute worker, with
// the data task's scheduling (priority 0 here). With the executor's threads: a stepped
// executor starts no worker thread.
TEST(MclComponentTest, TheLikelihoodWorkerIsAnExecutorThreadWithTheDataTasksScheduling) {
  Watchdog watchdog;
  HostUnderTest host(host_yaml(kOffice), register_test_classes);
  const std::string threads = host.executor().thread_report();
  const auto at = threads.find("mcl:likelihood");
  ASSERT_NE(at, std::string::npos) << threads;
  EXPECT_NE(threads.substr(at, threads.find('\n', at) - at).find("compute worker, not RT"), std::string::npos)
      << threads;
}

// global_candidates and the odometry check are parameters of the component: a host
// file sets them, and a value out of range is refused at load with its name.
TEST(MclComponentTest, GlobalCandidatesAndOdometryCheckAreParameters) {
  Watchdog watchdog(std::chrono::seconds(60));
  for (const char* bad : {"      global_candidates: 0\n", "      odometry_check_fraction: 2\n"}) {
    try {
      HostUnderTest host(host_yaml(kOffice, bad), register_test_classes);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const std::runtime_error& e) {
      const std::string name = std::string(bad).substr(6, std::string(bad).find(':') - 6);
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  HostUnderTest host(host_yaml(kOffice,
                               "      global_candidates: 3\n      odometry_check: 3\n"
                               "      odometry_check_fraction: 0.3\n      odometry_check_goodness: 0.6\n"),
                     register_test_classes, false, Stepping::kStepped);
  const tims::Address mcl = host.address_of("mcl");
  ASSERT_EQ(host.status(mcl), tims::msg::kEnabled) << host.log();
  wire::SampleHeader sh{};
  auto data = std::make_unique<MclData>();
  EXPECT_TRUE(host.stepper().run_until([&] { return host.get_data(mcl, sh, *data) && data->updates >= 3; }, kLimit))
      << host.log();
}

TEST(MclComponentTest, MissingMapPutsOnlyMclInErrorWithTheFileName) {
  Watchdog watchdog;
  HostUnderTest host(host_yaml("/nonexistent/robot_map.yaml"), register_test_classes, false, Stepping::kStepped);
  const tims::Address mcl = host.address_of("mcl");
  ASSERT_EQ(host.status(mcl), tims::msg::kError) << host.log();
  EXPECT_NE(host.log().find("/nonexistent/robot_map.yaml"), std::string::npos) << host.log();
  EXPECT_EQ(host.status(host.address_of("gen")), tims::msg::kEnabled) << host.log();
  (void)host.stepper().run_for(100 * rt::kNsPerMs);
  EXPECT_EQ(host.stats(host.address_of("gen")).data.cycles, 10u) << "the rest runs: a 10 ms task, 100 ms";
  const auto on = host.call(mcl, tims::msg::kOn);
  EXPECT_EQ(on.type, tims::msg::kError);  // ERROR for good: init() failed
}

TEST(MclComponentTest, MalformedMapNamesFileAndLine) {
  Watchdog watchdog;
  const auto dir = std::filesystem::temp_directory_path() / "rack_mcl_bad_map";
  std::filesystem::create_directories(dir);
  const auto yaml = dir / "bad.yaml";
  {
    std::ofstream out(yaml);
    out << "image: office.pgm\nresolution: fast\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\n"
           "free_thresh: 0.196\n";
  }
  HostUnderTest host(host_yaml(yaml.string()), register_test_classes, false, Stepping::kStepped);
  ASSERT_EQ(host.status(host.address_of("mcl")), tims::msg::kError) << host.log();
  EXPECT_NE(host.log().find(yaml.string() + ":2"), std::string::npos) << host.log();
  EXPECT_EQ(host.status(host.address_of("gen")), tims::msg::kEnabled) << host.log();
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rack::test
