// Scan3D in a real executor: the simulated 3-D scanner (ChassisSim standing still,
// ServoDriveSim nodding LadarSim in the office map's 2.5-D world) yields typed scans
// with the floor as ground plane; STORE_DATA writes a PCD file that reads back;
// GET_RANGE_IMAGE answers; PCD playback skips a malformed file (counted) and keeps
// running; with `odometry` a wall ahead of the driving robot stays thin, a NaN pose
// is counted and skipped, a silent odometry is an ERROR that recovers, one of the
// wrong class is refused by name; a host file without a source leaves only Scan3D in
// ERROR.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "../unit/test_support.h"
#include "wrong_type_producer.h"
#include "rack/components/class_ids.h"
#include "scan3d/scan3d_types.h"
#include "common/scan3d_geometry.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/robot.h"
#include "rack/rt/clock.h"
#include "rack/scan3d/pcd_file.h"
#include "scan3d/scan3d.h"

namespace rack::test {
namespace {

using interfaces::Scan3dData;

const std::string kOffice = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";

// A tool mailbox with slots large enough for a Scan3D sample (the shared test host's
// take 64 KiB).
class BigCaller {
 public:
  explicit BigCaller(HostUnderTest& host)
      : host_(host),
        mailbox_(tims::Address::make(host.executor().settings().system, tims::classes::kTool, 2, 1), 2, kSize),
        endpoint_(host.executor().router(), mailbox_, 10),
        buffer_(kSize) {
    host.executor().router().add(mailbox_);
  }
  ~BigCaller() { host_.executor().router().remove(mailbox_.address()); }
  BigCaller(const BigCaller&) = delete;
  BigCaller& operator=(const BigCaller&) = delete;

  HostUnderTest::Reply call(tims::Address dest, int8_t type, const void* body = nullptr, std::size_t size = 0) {
    const tims::ConstBuffer part{body, size};
    const auto r = endpoint_.call(dest, type, std::span<const tims::ConstBuffer>(&part, size == 0 ? 0 : 1),
                                  std::span<std::byte>(buffer_), kCallTimeoutNs);
    HostUnderTest::Reply out;
    out.status = r.status;
    if (r.status == tims::CallStatus::kOk) {
      out.type = r.reply.type;
      out.body.assign(reinterpret_cast<const char*>(r.body.data()), r.body.size());
    }
    return out;
  }
  bool get_scan(tims::Address dest, Scan3dData& out) {
    const auto r = call(dest, tims::msg::kGetData);
    if (r.type != tims::msg::kData || r.body.size() != sizeof(wire::SampleHeader) + sizeof out) return false;
    std::memcpy(&out, r.body.data() + sizeof(wire::SampleHeader), sizeof out);
    return true;
  }

 private:
  static constexpr uint32_t kSize = 2 * 1024 * 1024;
  HostUnderTest& host_;
  tims::Mailbox mailbox_;
  tims::Endpoint endpoint_;
  std::vector<std::byte> buffer_;
};

std::string scanner_yaml() {
  return R"(lcm: false
components:
  - name: chassis
    class: ChassisSim
    data_task: {priority: 0, period_ms: 20}
    params: {map: )" +
         kOffice + R"(, initial_x: 4.0, initial_y: 7.2, initial_phi: 0.0}
  - name: servo
    class: ServoDriveSim
    data_task: {priority: 0, period_ms: 10}
    params: {max_velocity: 2.0, acceleration: 8.0, position_min: -0.8, position_max: 0.8}
  - name: ladar
    class: LadarSim
    data_task: {priority: 0, period_ms: 40}
    params: {map: )" +
         kOffice + R"(, chassis: chassis, servo: servo, scan_mode: pitch, mount_x: 0.2, mount_z: 0.5,
             ceiling_height: 2.5, beams: 181, fov_deg: 180, range_max: 12.0, noise_sigma: 0.005}
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0, timeout_ms: 200, ring: 4, input_slots: 128}
    params: {ladar: ladar, servo: servo, mode: pitch, mount_x: 0.2, mount_z: 0.5, angle_min: -0.5, angle_max: 0.5,
             sweep_velocity: 1.0, ceiling_height: 2.2, store_dir: )" +
         std::filesystem::temp_directory_path().string() + R"(}
)";
}

TEST(Scan3dComponentTest, SweepsTheSimulatedScannerIntoTypedScans) {
  Watchdog watchdog(std::chrono::seconds(60));
  HostUnderTest host(scanner_yaml());
  BigCaller big(host);
  const tims::Address scan3d = host.address_of("scan3d");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kEnabled)) << host.log();
  auto* component = dynamic_cast<components::Scan3d*>(host.executor().find("scan3d"));
  ASSERT_NE(component, nullptr);
  ASSERT_TRUE(eventually([&] { return component->scans_published() >= 2; }, std::chrono::milliseconds(20000)))
      << host.log();
  auto scan = std::make_unique<Scan3dData>();
  ASSERT_TRUE(big.get_scan(scan3d, *scan));
  EXPECT_EQ(scan->mode, interfaces::kScan3dModePitch);
  EXPECT_GT(scan->ladar_scans, 10U);
  EXPECT_GT(scan->raw_points, scan->point_count);
  EXPECT_GT(scan->duration_ns, 500'000'000);
  EXPECT_EQ(scan->bad_input, 0U);
  // The floor of the simulated world is the ground plane (z = 0 in the robot frame).
  ASSERT_EQ(scan->ground_valid, 1);
  EXPECT_GT(scan->ground_c, 0.999F);
  EXPECT_NEAR(scan->ground_d, 0.0F, 0.03F);
  EXPECT_GT(scan->ground_points, 100U);
  EXPECT_GT(scan->object_points, 100U);   // the corridor's walls
  EXPECT_GT(scan->ceiling_points, 100U);  // the 2.5 m ceiling, above ceiling_height 2.2
  // Types follow the plane Scan3D found (ground_tolerance 0.05, ceiling_height 2.2 over
  // it); in the world, that plane is within 3 cm of z = 0 at the robot and tilted by at
  // most acos(ground_c) (RANSAC on a sweep: a slight tilt is possible), so a point r
  // metres out may sit r * tan(tilt) higher or lower than its height over the plane.
  const double tilt_slope = std::tan(std::acos(std::min(1.0, static_cast<double>(scan->ground_c))));
  for (uint32_t i = 0; i < scan->point_count; ++i) {
    const float h = scan->ground_a * scan->x[i] + scan->ground_b * scan->y[i] + scan->ground_c * scan->z[i] +
                    scan->ground_d;
    const double slack = 0.03 + std::hypot(scan->x[i], scan->y[i]) * tilt_slope;
    if (scan->type[i] == interfaces::kScanPointGround) {
      ASSERT_LE(std::fabs(h), 0.05F + 1e-4F);
      ASSERT_LT(std::fabs(scan->z[i]), 0.05 + slack);
    }
    if (scan->type[i] == interfaces::kScanPointCeiling) {
      // Above ceiling_height: the 2.5 m ceiling and the walls' tops.
      ASSERT_GT(h, 2.2F - 1e-4F);
      ASSERT_GT(scan->z[i], 2.2 - slack);
      ASSERT_LT(scan->z[i], 2.53 + slack);
    }
  }

  // STORE_DATA to a path: the file holds the scan.
  interfaces::Scan3dStoreData store;
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("rack_scan3d_store_" + std::to_string(::getpid()) + ".pcd"))
                               .string();
  wire::copy_text(store.path, path.c_str());
  auto r = big.call(scan3d, interfaces::kScan3dStoreData, &store, sizeof store);
  ASSERT_EQ(r.type, tims::msg::kOk) << r.error_text();
  scan3d::PcdCloud cloud;
  std::string error;
  ASSERT_TRUE(scan3d::read_pcd(path, cloud, error)) << error;
  EXPECT_GT(cloud.size(), 1000U);
  std::filesystem::remove(path);
  wire::copy_text(store.path, "/nonexistent/dir/scan.pcd");
  r = big.call(scan3d, interfaces::kScan3dStoreData, &store, sizeof store);
  EXPECT_EQ(r.type, tims::msg::kError);
  EXPECT_NE(r.error_text().find("/nonexistent/dir/scan.pcd"), std::string::npos) << r.error_text();
  r = big.call(scan3d, interfaces::kScan3dStoreData, &store, 10);  // malformed body
  EXPECT_EQ(r.type, tims::msg::kError);

  // GET_RANGE_IMAGE.
  interfaces::Scan3dRangeImageRequest req;
  req.angular_resolution_deg = 1.0F;
  r = big.call(scan3d, interfaces::kScan3dGetRangeImage, &req, sizeof req);
  ASSERT_EQ(r.type, interfaces::kScan3dRangeImageReply) << r.error_text();
  ASSERT_EQ(r.body.size(), sizeof(interfaces::Scan3dRangeImage));
  auto image = std::make_unique<interfaces::Scan3dRangeImage>();
  std::memcpy(image.get(), r.body.data(), sizeof *image);
  EXPECT_GT(image->width, 50U);
  EXPECT_GT(image->height, 20U);
  uint32_t seen = 0;
  for (uint32_t i = 0; i < image->width * image->height; ++i) seen += image->range[i] > 0.0F;
  EXPECT_GT(seen, image->width * image->height / 4);
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled);
}

TEST(Scan3dComponentTest, PlaysPcdFilesAndSkipsAMalformedOne) {
  Watchdog watchdog(std::chrono::seconds(60));
  const auto dir = std::filesystem::temp_directory_path() / ("rack_scan3d_play_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    std::ofstream good(dir / "a_good.pcd");
    good
        << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2500\nHEIGHT 1\nPOINTS 2500\nDATA ascii\n";
    for (int i = 0; i < 50; ++i) {
      for (int j = 0; j < 50; ++j) good << 0.1 * i << " " << 0.1 * j - 2.5 << " 0.0\n";  // a floor
    }
    std::ofstream bad(dir / "b_bad.pcd");
    bad << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n";
  }
  HostUnderTest host(R"(lcm: false
components:
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0, timeout_ms: 20, ring: 4}
    params: {pcd: )" +
                     dir.string() + R"(, pcd_period_ms: 50, voxel_size: 0.0, outlier_neighbours: 0}
  - name: gen
    class: Generator
    autostart: true
    data_task: {period_ms: 10}
)");
  BigCaller big(host);
  const tims::Address scan3d = host.address_of("scan3d");
  auto* component = dynamic_cast<components::Scan3d*>(host.executor().find("scan3d"));
  ASSERT_NE(component, nullptr);
  ASSERT_TRUE(eventually([&] { return component->scans_published() >= 3 && component->bad_input() >= 3; }))
      << host.log();
  auto scan = std::make_unique<Scan3dData>();
  ASSERT_TRUE(big.get_scan(scan3d, *scan));
  EXPECT_EQ(scan->mode, interfaces::kScan3dModeFile);
  EXPECT_EQ(scan->point_count, 2500U);
  EXPECT_EQ(scan->ground_points, 2500U);
  EXPECT_GE(scan->bad_input, 1U);
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled) << "a malformed file is skipped, not fatal";
  EXPECT_EQ(host.status(host.address_of("gen")), tims::msg::kEnabled);
  std::filesystem::remove_all(dir);
}

// A "ladar" that publishes another class's samples (WrongTypeProducer: ServoDriveData
// where a LadarData is expected): every one is dropped, counted as malformed input
// (GET_STATS) and as bad input of the scan, and logged with its source; Scan3D stays
// ENABLED until the ladar has been silent (no usable scan) for silence_ms.
TEST(Scan3dComponentTest, SamplesOfTheWrongTypeAreCountedAsMalformedAndSkipped) {
  Watchdog watchdog(std::chrono::seconds(60));
  HostUnderTest host(R"(lcm: false
components:
  - name: servo
    class: ServoDriveSim
    data_task: {priority: 0, period_ms: 10}
  - name: ladar
    class: WrongTypeLadar
    data_task: {priority: 0, period_ms: 20}
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0, timeout_ms: 200, ring: 4, input_slots: 16}
    params: {ladar: ladar, servo: servo, mode: pitch, silence_ms: 30000}
)",
                     [](ComponentRegistry& r) {
                       r.add({"WrongTypeLadar", class_ids::kLadar, "test: publishes ServoDriveData",
                              [] { return std::make_unique<WrongTypeProducer>(); }});
                     },
                     /*capture_gdos=*/true);
  const tims::Address scan3d = host.address_of("scan3d");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kEnabled)) << host.log();
  auto* component = dynamic_cast<components::Scan3d*>(host.executor().find("scan3d"));
  ASSERT_NE(component, nullptr);
  ASSERT_TRUE(eventually([&] { return component->bad_input() >= 5 && host.stats(scan3d).malformed >= 5; }))
      << host.log();
  EXPECT_EQ(component->scans_published(), 0U);
  ASSERT_TRUE(eventually([&] {
    return host.gdos_log().find("input: dropped a DATA message of ") != std::string::npos;
  })) << host.gdos_log();
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled) << "a bad sample is skipped, not fatal";
  EXPECT_EQ(host.status(host.address_of("servo")), tims::msg::kEnabled);
}

// ---------------------------------------------------------------------------
// Motion compensation in a real executor: the simulated robot drives at 0.5 m/s
// towards the far wall of a 10 m x 6 m room (its face at x = 9.8 m, 4.6 m ahead of
// the ladar at the start) while Scan3D
// sweeps with `odometry` (an Odometry on the chassis; no noise, so any thickness
// is the compensation's).

constexpr double kRoomWallX = 9.8;

// A room of 10 m x 6 m (5 cm cells), closed by 20 cm walls; the map's YAML path.
std::string write_room(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  constexpr int kW = 200, kH = 120, kWall = 4;
  std::string pgm = "P5\n" + std::to_string(kW) + " " + std::to_string(kH) + "\n255\n";
  for (int row = 0; row < kH; ++row) {
    for (int col = 0; col < kW; ++col) {
      const bool wall = row < kWall || row >= kH - kWall || col < kWall || col >= kW - kWall;
      pgm += static_cast<char>(wall ? 0 : 254);
    }
  }
  std::ofstream(dir / "room.pgm", std::ios::binary) << pgm;
  std::ofstream(dir / "room.yaml") << "image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                                      "occupied_thresh: 0.65\nfree_thresh: 0.196\n";
  return (dir / "room.yaml").string();
}

std::string driving_yaml(const std::string& map) {
  return R"(lcm: false
components:
  - name: chassis
    class: ChassisSim
    data_task: {priority: 0, period_ms: 20, ring: 500}
    params: {map: )" +
         map + R"(, initial_x: 5.0, initial_y: 3.0, initial_phi: 0.0, noise_xy: 0.0, noise_phi: 0.0,
             noise_phi_per_m: 0.0, watchdog_ms: 1000}
  - name: odometry
    class: Odometry
    data_task: {priority: 0, ring: 500}
    params: {chassis: chassis}
  - name: servo
    class: ServoDriveSim
    data_task: {priority: 0, period_ms: 10}
    params: {max_velocity: 2.0, acceleration: 8.0, position_min: -0.8, position_max: 0.8}
  - name: ladar
    class: LadarSim
    data_task: {priority: 0, period_ms: 40}
    params: {map: )" +
         map + R"(, chassis: chassis, servo: servo, scan_mode: pitch, mount_x: 0.2, mount_z: 0.5,
             ceiling_height: 2.5, beams: 181, fov_deg: 180, range_max: 12.0, noise_sigma: 0.0}
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0, timeout_ms: 200, ring: 4, input_slots: 256}
    params: {ladar: ladar, servo: servo, odometry: odometry, mode: pitch, mount_x: 0.2, mount_z: 0.5,
             angle_min: -0.5, angle_max: 0.5, sweep_velocity: 1.0, voxel_size: 0.0, outlier_neighbours: 0}
)";
}

struct WallBand {
  uint32_t n = 0;
  double min = 1e9, max = -1e9, sum = 0.0;
  [[nodiscard]] double thickness() const { return max - min; }
  [[nodiscard]] double mean() const { return n ? sum / n : 0.0; }
};
// The wall ahead in a scan: points within 1 m of the robot's axis, between floor and
// ceiling, farther than 2 m (the side walls are 2.8 m to either side).
WallBand wall_ahead(const Scan3dData& s) {
  WallBand b;
  for (uint32_t i = 0; i < s.point_count; ++i) {
    if (std::fabs(s.y[i]) > 1.0F || s.z[i] < 0.2F || s.z[i] > 2.3F || s.x[i] < 2.0F) continue;
    const double x = s.x[i];
    ++b.n;
    b.min = std::min(b.min, x);
    b.max = std::max(b.max, x);
    b.sum += x;
  }
  return b;
}

TEST(Scan3dComponentTest, OdometryKeepsTheWallAheadThinWhileTheRobotDrives) {
  Watchdog watchdog(std::chrono::seconds(90));
  const auto dir = std::filesystem::temp_directory_path() / ("rack_scan3d_room_" + std::to_string(::getpid()));
  HostUnderTest host(driving_yaml(write_room(dir)));
  BigCaller big(host);
  const tims::Address scan3d = host.address_of("scan3d");
  const tims::Address chassis = host.address_of("chassis");
  const tims::Address odometry = host.address_of("odometry");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kEnabled)) << host.log();
  auto* component = dynamic_cast<components::Scan3d*>(host.executor().find("scan3d"));
  ASSERT_NE(component, nullptr);
  ASSERT_TRUE(eventually([&] { return component->scans_published() >= 1; }, std::chrono::milliseconds(20000)))
      << host.log();

  // Drive straight ahead at 0.5 m/s (MOVE keeps the chassis' watchdog fed).
  interfaces::ChassisSetActivePilot pilot;
  pilot.pilot = host.endpoint().address().raw();
  ASSERT_EQ(host.call_with(chassis, interfaces::kChassisSetActivePilot, pilot).type, tims::msg::kOk);
  interfaces::ChassisMove move;
  move.vx = 0.5;
  const uint64_t before = component->scans_published();
  // Two sweeps after the start: the second lies wholly in the motion at full speed.
  ASSERT_TRUE(eventually(
      [&] {
        (void)host.call_with(chassis, interfaces::kChassisMove, move);
        return component->scans_published() >= before + 2;
      },
      std::chrono::milliseconds(20000)))
      << host.log();
  auto scan = std::make_unique<Scan3dData>();
  wire::SampleHeader sh;
  {
    const auto r = big.call(scan3d, tims::msg::kGetData);
    ASSERT_EQ(r.type, tims::msg::kData);
    ASSERT_EQ(r.body.size(), sizeof(wire::SampleHeader) + sizeof *scan);
    std::memcpy(&sh, r.body.data(), sizeof sh);
    std::memcpy(scan.get(), r.body.data() + sizeof sh, sizeof *scan);
  }
  // The robot at the scan's time (its END with odometry) and at its start.
  interfaces::ChassisData at_end, at_start;
  wire::SampleHeader csh;
  ASSERT_TRUE(host.get_data(chassis, csh, at_end, sh.time_ns));
  EXPECT_EQ(csh.time_ns, sh.time_ns) << "the scan's time is a chassis sample's (its last 2-D scan's)";
  ASSERT_TRUE(host.get_data(chassis, csh, at_start, sh.time_ns - scan->duration_ns));
  const double travelled = at_end.truth_x - at_start.truth_x;
  interfaces::OdometryData odo;
  ASSERT_TRUE(host.get_data(odometry, csh, odo, sh.time_ns));
  // Stop before judging (the room's wall is close enough to be reached in a few seconds).
  move.vx = 0.0;
  (void)host.call_with(chassis, interfaces::kChassisMove, move);

  EXPECT_EQ(scan->bad_input, 0U);
  const WallBand wall = wall_ahead(*scan);
  std::printf(
      "driving scan: %.2f s, robot travelled %.3f m during it; wall ahead %u points, %.4f m thick at x %.3f "
      "(expected %.3f)\n",
      static_cast<double>(scan->duration_ns) * 1e-9, travelled, wall.n, wall.thickness(), wall.mean(),
      kRoomWallX - at_end.truth_x);
  // Without compensation the wall's points spread over what the robot drove while the
  // beams swept the wall (about half the sweep here: 0.24 m thick, 0.38 m off, when
  // this test was run with compensation switched off in the component).
  ASSERT_GT(travelled, 0.25) << "the robot must drive during the sweep for this test to mean anything";
  ASSERT_GT(wall.n, 100U);
  EXPECT_LT(wall.thickness(), 0.03);
  // Where the wall is from the robot at the scan's end (the cell edge at 9.8 m).
  EXPECT_NEAR(wall.mean(), kRoomWallX - at_end.truth_x, 0.03);
  EXPECT_NEAR(odo.x, at_end.truth_x - 5.0, 0.01) << "noise-free odometry follows the truth";
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled);
  std::filesystem::remove_all(dir);
}

// An Odometry for the failure paths: publishes a standing robot every cycle, stamped
// now; `pause` silences it (it stays ENABLED), `poison_every` makes every n-th pose
// NaN, `lag_ns` stamps the poses that much in the past (a clock behind the ladar's).
// Test code: priority 0.
class ControlledOdometry final : public DataComponent<interfaces::OdometryData> {
 public:
  ControlledOdometry() : DataComponent(DataTaskMode::kPeriodic) {}
  std::atomic<bool> pause{false};
  std::atomic<uint32_t> poison_every{0};
  std::atomic<int64_t> lag_ns{0};

 protected:
  HookResult loop() override {
    if (pause.load(std::memory_order_relaxed)) return HookResult::kOk;
    interfaces::OdometryData d{};
    const uint32_t every = poison_every.load(std::memory_order_relaxed);
    if (every != 0 && ++cycles_ % every == 0) d.x = std::nan("");
    publish(d, rt::host_time_ns() - lag_ns.load(std::memory_order_relaxed));
    return HookResult::kOk;
  }

 private:
  uint32_t cycles_ = 0;
};

// A pose that is not finite is counted and skipped; an odometry that falls silent
// puts Scan3D in ERROR with a message naming it, and Scan3D recovers (on() retries)
// once the poses come back; poses that keep coming but lag the scans by more than
// silence_ms (none covers a scan) are an ERROR too.
TEST(Scan3dComponentTest, BadOrSilentOdometryIsCountedOrAnError) {
  Watchdog watchdog(std::chrono::seconds(90));
  HostUnderTest host(R"(lcm: false
components:
  - name: chassis
    class: ChassisSim
    data_task: {priority: 0, period_ms: 20}
    params: {map: )" + kOffice +
                         R"(, initial_x: 4.0, initial_y: 7.2, initial_phi: 0.0}
  - name: servo
    class: ServoDriveSim
    data_task: {priority: 0, period_ms: 10}
    params: {max_velocity: 2.0, acceleration: 8.0, position_min: -0.8, position_max: 0.8}
  - name: ladar
    class: LadarSim
    data_task: {priority: 0, period_ms: 40}
    params: {map: )" + kOffice +
                         R"(, chassis: chassis, servo: servo, scan_mode: pitch, mount_x: 0.2, mount_z: 0.5,
             ceiling_height: 2.5, beams: 91, fov_deg: 180, range_max: 12.0}
  - name: odo
    class: ControlledOdometry
    data_task: {priority: 0, period_ms: 10}
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0, timeout_ms: 100, ring: 4, input_slots: 256}
    params: {ladar: ladar, servo: servo, odometry: odo, mode: pitch, mount_x: 0.2, mount_z: 0.5, angle_min: -0.4,
             angle_max: 0.4, sweep_velocity: 1.0, silence_ms: 500}
)",
                     [](ComponentRegistry& r) {
                       r.add({"ControlledOdometry", class_ids::kOdometry, "test: an odometry that can fall silent",
                              [] { return std::make_unique<ControlledOdometry>(); }});
                     },
                     /*capture_gdos=*/true);
  const tims::Address scan3d = host.address_of("scan3d");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kEnabled)) << host.log();
  auto* component = dynamic_cast<components::Scan3d*>(host.executor().find("scan3d"));
  auto* odo = dynamic_cast<ControlledOdometry*>(host.executor().find("odo"));
  ASSERT_NE(component, nullptr);
  ASSERT_NE(odo, nullptr);

  // Every 25th pose NaN: counted, logged, skipped; the scans go on.
  odo->poison_every.store(25);
  const uint64_t scans = component->scans_published();
  ASSERT_TRUE(eventually([&] { return component->bad_input() >= 5 && component->scans_published() >= scans + 2; },
                         std::chrono::milliseconds(20000)))
      << host.log();
  ASSERT_TRUE(eventually([&] {
    return host.gdos_log().find("skipped an odometry pose: x, y or phi is not a finite number") != std::string::npos;
  })) << host.gdos_log();
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled) << "a bad pose is skipped, not fatal";
  odo->poison_every.store(0);

  // Silent (still ENABLED, sending nothing): ERROR, with the odometry named.
  odo->pause.store(true);
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kError)) << host.log();
  ASSERT_TRUE(eventually([&] { return host.gdos_log().find("sent no pose for 500 ms") != std::string::npos; }))
      << host.gdos_log();
  EXPECT_NE(host.gdos_log().find("the odometry Odometry("), std::string::npos) << host.gdos_log();
  EXPECT_EQ(host.status(host.address_of("odo")), tims::msg::kEnabled);

  // Back: Scan3D retries on() and sweeps again.
  odo->pause.store(false);
  const uint64_t again = component->scans_published();
  ASSERT_TRUE(eventually([&] { return component->scans_published() >= again + 2; }, std::chrono::milliseconds(30000)))
      << host.log();
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled);

  // Poses 2 s behind the scans: they arrive, but cover none of them.
  odo->lag_ns.store(2'000'000'000);
  ASSERT_TRUE(eventually([&] {
    return host.gdos_log().find("has no pose for the ladar scan at") != std::string::npos;
  })) << host.gdos_log();
  EXPECT_NE(host.gdos_log().find("ms older (silence_ms 500)"), std::string::npos) << host.gdos_log();
  odo->lag_ns.store(0);
}

// `odometry` must name an Odometry or a Position: anything else is a setup error
// that names it.
TEST(Scan3dComponentTest, OdometryOfTheWrongClassIsAnErrorNamingIt) {
  Watchdog watchdog(std::chrono::seconds(30));
  HostUnderTest host(R"(lcm: false
components:
  - name: servo
    class: ServoDriveSim
    data_task: {priority: 0, period_ms: 10}
  - name: ladar
    class: WrongTypeLadar
    data_task: {priority: 0, period_ms: 20}
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0}
    params: {ladar: ladar, servo: servo, odometry: servo}
)",
                     [](ComponentRegistry& r) {
                       r.add({"WrongTypeLadar", class_ids::kLadar, "test: publishes ServoDriveData",
                              [] { return std::make_unique<WrongTypeProducer>(); }});
                     });
  const tims::Address scan3d = host.address_of("scan3d");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kError));
  const auto r = host.call(scan3d, tims::msg::kOn);
  EXPECT_EQ(r.type, tims::msg::kError);
  EXPECT_NE(r.error_text().find("odometry 'servo' is ServoDrive("), std::string::npos) << r.error_text();
  EXPECT_NE(r.error_text().find("neither an Odometry nor a Position"), std::string::npos) << r.error_text();
}

TEST(Scan3dComponentTest, WithoutASourceOnlyScan3dIsInError) {
  Watchdog watchdog(std::chrono::seconds(30));
  HostUnderTest host(R"(lcm: false
components:
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0}
  - name: gen
    class: Generator
    autostart: true
    data_task: {period_ms: 10}
)");
  const tims::Address scan3d = host.address_of("scan3d");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kError));
  const auto r = host.call(scan3d, tims::msg::kOn);
  EXPECT_EQ(r.type, tims::msg::kError);
  EXPECT_NE(r.error_text().find("pcd"), std::string::npos) << r.error_text();
  // Its commands are answered at once, not queued for a data task that does not run.
  const auto image = host.call(scan3d, interfaces::kScan3dGetRangeImage);
  EXPECT_EQ(image.type, tims::msg::kError);
  EXPECT_NE(image.error_text().find("not ENABLED"), std::string::npos) << image.error_text();
  EXPECT_EQ(host.status(host.address_of("gen")), tims::msg::kEnabled);
}

}  // namespace
}  // namespace rack::test
