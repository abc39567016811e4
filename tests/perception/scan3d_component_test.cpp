// Scan3D in a real executor: the simulated 3-D scanner (ChassisSim standing still,
// ServoDriveSim nodding LadarSim in the office map's 2.5-D world) yields typed scans
// with the floor as ground plane; STORE_DATA writes a PCD file that reads back;
// GET_RANGE_IMAGE answers; PCD playback skips a malformed file (counted) and keeps
// running; a host file without a source leaves only Scan3D in ERROR.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "../unit/test_support.h"
#include "wrong_type_producer.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/perception.h"
#include "rack/interfaces/robot.h"
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
    params: {map: )" + kOffice + R"(, initial_x: 4.0, initial_y: 7.2, initial_phi: 0.0}
  - name: servo
    class: ServoDriveSim
    data_task: {priority: 0, period_ms: 10}
    params: {max_velocity: 2.0, acceleration: 8.0, position_min: -0.8, position_max: 0.8}
  - name: ladar
    class: LadarSim
    data_task: {priority: 0, period_ms: 40}
    params: {map: )" + kOffice + R"(, chassis: chassis, servo: servo, scan_mode: pitch, mount_x: 0.2, mount_z: 0.5,
             ceiling_height: 2.5, beams: 181, fov_deg: 180, range_max: 12.0, noise_sigma: 0.005}
  - name: scan3d
    class: Scan3D
    autostart: true
    data_task: {priority: 0, timeout_ms: 200, ring: 4, input_slots: 128}
    params: {ladar: ladar, servo: servo, mode: pitch, mount_x: 0.2, mount_z: 0.5, angle_min: -0.5, angle_max: 0.5,
             sweep_velocity: 1.0, ceiling_height: 2.2, store_dir: )" + std::filesystem::temp_directory_path().string() + R"(}
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
  for (uint32_t i = 0; i < scan->point_count; ++i) {
    if (scan->type[i] == interfaces::kScanPointGround) {
      ASSERT_LT(std::fabs(scan->z[i]), 0.08F);  // ground_tolerance 0.05 around a plane within 3 cm of z = 0
    }
    if (scan->type[i] == interfaces::kScanPointCeiling) {
      // Above ceiling_height (2.2 m over the ground plane): the ceiling and the walls' tops.
      ASSERT_GT(scan->z[i], 2.17F);
      ASSERT_LT(scan->z[i], 2.56F);
    }
  }

  // STORE_DATA to a path: the file holds the scan.
  interfaces::Scan3dStoreData store;
  const std::string path = (std::filesystem::temp_directory_path() / ("rack_scan3d_store_" + std::to_string(::getpid()) + ".pcd")).string();
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
    good << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2500\nHEIGHT 1\nPOINTS 2500\nDATA ascii\n";
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
    params: {pcd: )" + dir.string() + R"(, pcd_period_ms: 50, voxel_size: 0.0, outlier_neighbours: 0}
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
                       r.add({"WrongTypeLadar", tims::classes::kLadar, "test: publishes ServoDriveData",
                              [] { return std::make_unique<WrongTypeProducer>(); }});
                     },
                     /*capture_gdos=*/true);
  const tims::Address scan3d = host.address_of("scan3d");
  ASSERT_TRUE(host.wait_status(scan3d, tims::msg::kEnabled)) << host.log();
  auto* component = dynamic_cast<components::Scan3d*>(host.executor().find("scan3d"));
  ASSERT_NE(component, nullptr);
  ASSERT_TRUE(eventually([&] { return component->bad_input() >= 5 && host.stats(scan3d).malformed >= 5; })) << host.log();
  EXPECT_EQ(component->scans_published(), 0U);
  ASSERT_TRUE(eventually([&] { return host.gdos_log().find("input: dropped a DATA message of ") != std::string::npos; }))
      << host.gdos_log();
  EXPECT_EQ(host.status(scan3d), tims::msg::kEnabled) << "a bad sample is skipped, not fatal";
  EXPECT_EQ(host.status(host.address_of("servo")), tims::msg::kEnabled);
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
