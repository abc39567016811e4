// Integration: the simulated 3-D scanner (configs/sim_scan3d.yaml) in the real rackd,
// driven by the real rackctl over TiMS/LCM on its own bus, with a watchdog: the
// shipped host file is valid, Scan3D publishes typed scans (floor, walls, ceiling),
// and STORE_DATA from rackctl writes a PCD file into store_dir.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

class Scan3dSimTest : public ::testing::Test {
 protected:
  Scan3dSimTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void TearDown() override {
    if (rackd_ && rackd_->running()) {
      rackd_->signal(SIGTERM);
      EXPECT_EQ(rackd_->wait_exit(30s), std::optional<int>(0)) << rackd_->err();
    }
  }
  // The shipped file with its map paths made absolute (it names them relative to the
  // repository root, where the README runs rackd).
  std::string host_file() {
    std::string text = read_file(kConfigs + "/sim_scan3d.yaml");
    const std::string rel = "map: maps/office.yaml";
    int replaced = 0;
    for (auto at = text.find(rel); at != std::string::npos; at = text.find(rel, at + 1), ++replaced) {
      text.replace(at, rel.size(), "map: " + kConfigs + "/maps/office.yaml");
    }
    EXPECT_EQ(replaced, 2) << "sim_scan3d.yaml names the map for the chassis and the ladar";
    // STORE_DATA writes into the test's directory instead of rackd's working directory.
    const std::string store = "store_dir: /tmp";
    const auto at = text.find(store);
    EXPECT_NE(at, std::string::npos) << "sim_scan3d.yaml sets store_dir";
    if (at != std::string::npos) text.replace(at, store.size(), "store_dir: \"" + dir_.path().string() + "\"");
    return dir_.write("sim_scan3d.yaml", text).string();
  }
  RunResult ctl(std::vector<std::string> args) {
    // A scan is 12 datagrams of 60 KB at once: a larger socket buffer for rackctl, as
    // the README says for large messages (the kernel caps it at net.core.rmem_max).
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url() + "&recv_buf_size=4194304", "--discover-ms", "3000"});
    return run(args, 30s);
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::unique_ptr<Process> rackd_;
};

TEST_F(Scan3dSimTest, TheShippedHostFilesAreValid) {
  auto r = run({kRackd, "--check", host_file()}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  // configs/objrecog.yaml (camera and laser object recognition), when OpenCV's
  // contrib modules gave this rackd the ObjRecogCamera class.
  const auto classes = run({kRackd, "--list-classes"}, 30s);
  ASSERT_EQ(classes.exit_code, 0) << classes.describe();
  if (classes.out.find("ObjRecogCamera  (class ") == std::string::npos) {
    GTEST_SKIP() << "ObjRecogCamera is not built into this rackd (libopencv-contrib-dev missing)";
  }
  std::string text = read_file(kConfigs + "/objrecog.yaml");
  const std::string rel = "map: maps/office.yaml";
  for (auto at = text.find(rel); at != std::string::npos; at = text.find(rel, at + 1)) {
    text.replace(at, rel.size(), "map: " + kConfigs + "/maps/office.yaml");
  }
  r = run({kRackd, "--check", dir_.write("objrecog.yaml", text).string()}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

TEST_F(Scan3dSimTest, ScansAreTypedAndStoreDataWritesAPcdFile) {
  rackd_ = std::make_unique<Process>(std::vector<std::string>{kRackd, host_file(), "--lcm", bus_.url()}, dir_.path(),
                                     "rackd");
  ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  std::optional<Json> scan;
  const auto deadline = std::chrono::steady_clock::now() + 40s;
  while (std::chrono::steady_clock::now() < deadline) {
    const RunResult r = ctl({"get-data", "scan3d"});
    if (r.exit_code == 0) {
      auto j = parse_json(r.out);
      if (j && j->at("data").is_object() && j->at("data").at("scan_number").number >= 1) {
        scan = j->at("data");
        break;
      }
    }
    std::this_thread::sleep_for(500ms);
  }
  ASSERT_TRUE(scan.has_value()) << "no 3-D scan from rackd: " << rackd_->err();
  EXPECT_EQ(scan->at("mode").number, 1);  // pitch
  EXPECT_EQ(scan->at("ground_valid").number, 1);
  EXPECT_GT(scan->at("ground_c").number, 0.999);
  EXPECT_GT(scan->at("ground_points").number, 100);
  EXPECT_GT(scan->at("object_points").number, 100);
  EXPECT_GT(scan->at("ceiling_points").number, 100);
  EXPECT_GT(scan->at("ladar_scans").number, 30);
  EXPECT_EQ(scan->at("bad_input").number, 0);

  const RunResult store = ctl({"send", "scan3d", "22"});
  ASSERT_EQ(store.exit_code, 0) << store.describe();
  bool found = false;
  for (const auto& e : std::filesystem::directory_iterator(dir_.path())) {
    const std::string name = e.path().filename().string();
    if (name.rfind("scan3d_", 0) == 0 && e.path().extension() == ".pcd") {
      found = true;
      EXPECT_GT(std::filesystem::file_size(e.path()), 10000U);
      EXPECT_EQ(read_file(e.path()).rfind("# .PCD v0.7", 0), 0U);
    }
  }
  EXPECT_TRUE(found) << "STORE_DATA wrote no scan3d_<n>.pcd in store_dir";
}

}  // namespace
}  // namespace rack::test
