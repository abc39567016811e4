// TrajectoryWriter's pure parts: the error of an estimated trajectory against a
// reference (ATE, lost poses, rotation error, matching by time) and the reader of
// `t x y theta` files (every malformed line rejected with file:line).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "evaluator/trajectory_writer.h"
#include "hostile_files.h"

namespace rack::test {
namespace {

using components::read_trajectory_file;
using components::TimedPose;
using components::trajectory_error;

TEST(TrajectoryErrorTest, AteLostAndRotationOverMatchedReferencePoses) {
  // Estimates at 0, 1, 2, 3 s; the reference at 0.5 (between two: interpolated),
  // 2 (exact), 3 (exact, 1 m off: lost) and 10 s (after the last: unmatched).
  const std::vector<TimedPose> estimate = {
      {0.0, 0.0, 0.0, 0.0}, {1.0, 1.0, 0.0, 0.1}, {2.0, 2.0, 0.0, 0.0}, {3.0, 3.0, 1.0, 0.0}};
  const std::vector<TimedPose> reference = {
      {0.5, 0.5, 0.0, 0.05}, {2.0, 2.0, 0.3, 0.0}, {3.0, 3.0, 0.0, 0.2}, {10.0, 0.0, 0.0, 0.0}};
  const auto e = trajectory_error(estimate, reference, 0.5, 1.5);
  EXPECT_EQ(e.reference, 4U);
  EXPECT_EQ(e.matched, 3U);
  EXPECT_EQ(e.lost, 1U);
  EXPECT_NEAR(e.ate_rmse, std::sqrt((0.0 + 0.09 + 1.0) / 3.0), 1e-12);
  EXPECT_NEAR(e.max_error, 1.0, 1e-12);
  EXPECT_NEAR(e.rotation_rmse, std::sqrt((0.0 + 0.0 + 0.04) / 3.0), 1e-12);
  // A gap longer than max_gap is not interpolated across.
  EXPECT_EQ(trajectory_error(estimate, reference, 0.5, 0.5).matched, 2U);  // 0.5 s is between estimates 1 s apart
  const std::vector<TimedPose> sparse = {{0.0, 0.0, 0.0, 0.0}, {2.0, 2.0, 0.0, 0.0}};
  EXPECT_EQ(trajectory_error(sparse, {{1.0, 1.0, 0.0, 0.0}}, 0.5, 1.5).matched, 0U);
  EXPECT_EQ(trajectory_error(sparse, {{1.0, 1.0, 0.0, 0.0}}, 0.5, 2.0).matched, 1U);
}

TEST(TrajectoryErrorTest, HeadingErrorTakesTheShorterWayRound) {
  const double pi = std::numbers::pi;
  const std::vector<TimedPose> estimate = {{1.0, 0.0, 0.0, pi - 0.05}};
  const auto e = trajectory_error(estimate, {{1.0, 0.0, 0.0, -pi + 0.05}}, 0.5, 1.0);
  EXPECT_NEAR(e.rotation_rmse, 0.1, 1e-9);
}

class TrajectoryFileTest : public ::testing::Test {
 protected:
  std::string write(const std::string& text) {
    path_ = std::filesystem::temp_directory_path() /
            ("rack_traj_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".txt");
    std::ofstream(path_) << text;
    return path_.string();
  }
  void TearDown() override { std::filesystem::remove(path_); }
  std::string error_of(const std::string& text) {
    const std::string p = write(text);
    try {
      (void)read_trajectory_file(p);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path path_;
};

TEST_F(TrajectoryFileTest, ReadsPosesSkippingCommentsAndBlankLines) {
  const auto poses = read_trajectory_file(write("# t x y theta\n\n1000.0 1 2 0.5\n1000.2 1.5 2 0.25 extra\n"));
  ASSERT_EQ(poses.size(), 2U);
  EXPECT_DOUBLE_EQ(poses[1].t, 1000.2);
  EXPECT_DOUBLE_EQ(poses[1].x, 1.5);
  EXPECT_DOUBLE_EQ(poses[1].phi, 0.25);
}

TEST(TrajectoryTextTest, ParsesFromMemoryWithCrlfAndNamesTheSourceInErrors) {
  const auto poses = components::parse_trajectory_text("1 0 0 0\r\n2 1 0 0\r\n", "mem");
  ASSERT_EQ(poses.size(), 2U);
  EXPECT_DOUBLE_EQ(poses[1].x, 1.0);
  try {
    (void)components::parse_trajectory_text("1 0 0 0\n2 1 0", "mem");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("mem:2: expected 't x y theta', found 3 field(s)"), std::string::npos)
        << e.what();
  }
}

TEST_F(TrajectoryFileTest, MalformedLinesAreRejectedWithFileAndLine) {
  EXPECT_NE(error_of("1 2 3 4\n2 2 3\n").find(":2: expected 't x y theta', found 3 field(s)"), std::string::npos);
  EXPECT_NE(error_of("1 2 x 4\n").find(":1: 'x' is not a number"), std::string::npos);
  EXPECT_NE(error_of("1 2 nan 4\n").find(":1: 'nan' is not finite"), std::string::npos);
  EXPECT_NE(error_of("2 0 0 0\n1 0 0 0\n").find(":2: time 1.000000 goes backwards"), std::string::npos);
  EXPECT_NE(error_of("1 2 3 4e\n").find("is not a number"), std::string::npos);
  try {
    (void)read_trajectory_file("/nonexistent/ref.txt");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/ref.txt: cannot open the trajectory file"), std::string::npos)
        << e.what();
  }
}

// A reference that is a FIFO with no writer, a directory or a device is refused with
// what it is (the ifstream it replaced waited for ever on the FIFO, in rackd's init()).
TEST_F(TrajectoryFileTest, AFifoADirectoryOrADeviceIsRefusedNotWaitedOn) {
  HostileDir dir("traj");
  HangGuard guard("read_trajectory_file on a FIFO");
  const std::pair<std::string, std::string> cases[] = {{dir.fifo("ref.fifo"), "is a FIFO, not a regular file"},
                                                       {dir.subdir("ref.d"), "is a directory, not a regular file"},
                                                       {"/dev/zero", "is a character device, not a regular file"}};
  for (const auto& [path, why] : cases) {
    try {
      (void)read_trajectory_file(path);
      ADD_FAILURE() << path << ": no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": the trajectory file " + why), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace rack::test
