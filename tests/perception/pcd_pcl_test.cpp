// Our PCD reader and writer against PCL's own (pcl_io, linked by this test only):
// files PCL writes in each of its three encodings read back point for point, and a
// file STORE_DATA writes loads in PCL.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>

#include "scan3d/scan3d_types.h"
#include "rack/scan3d/pcd_file.h"

namespace rack::test {
namespace {

enum class Encoding { kAscii, kBinary, kBinaryCompressed };

std::string temp_path(const std::string& what) {
  return (std::filesystem::temp_directory_path() / ("rack_pcd_pcl_" + what + "_" + std::to_string(::getpid()) + ".pcd"))
      .string();
}

// A cloud that compresses as real scans do (smooth coordinates, repeated values) plus
// a NaN hole, as organised clouds have.
pcl::PointCloud<pcl::PointXYZI> make_cloud(std::size_t n) {
  pcl::PointCloud<pcl::PointXYZI> c;
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0F, 0.002F);
  for (std::size_t i = 0; i < n; ++i) {
    pcl::PointXYZI p;
    p.x = 3.0F + noise(rng);
    p.y = -2.0F + 0.001F * static_cast<float>(i % 4000);
    p.z = 0.01F * static_cast<float>(i / 4000);
    p.intensity = static_cast<float>(i % 256);
    c.push_back(p);
  }
  c[5].x = std::numeric_limits<float>::quiet_NaN();
  return c;
}

class PcdPclTest : public ::testing::TestWithParam<Encoding> {};

TEST_P(PcdPclTest, FilesPclWritesReadBackPointForPoint) {
  const auto cloud = make_cloud(20000);
  const std::string path = temp_path("in");
  pcl::PCDWriter writer;
  int rc = 0;
  switch (GetParam()) {
    case Encoding::kAscii: rc = writer.writeASCII(path, cloud, 8); break;
    case Encoding::kBinary: rc = writer.writeBinary(path, cloud); break;
    case Encoding::kBinaryCompressed: rc = writer.writeBinaryCompressed(path, cloud); break;
  }
  ASSERT_EQ(rc, 0);
  scan3d::PcdCloud read;
  std::string error;
  ASSERT_TRUE(scan3d::read_pcd(path, read, error)) << error;
  EXPECT_EQ(read.declared_points, cloud.size());
  EXPECT_EQ(read.non_finite, 1U);
  ASSERT_EQ(read.size(), cloud.size() - 1);
  std::size_t j = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (i == 5) continue;
    ASSERT_NEAR(read.x[j], cloud[i].x, 1e-6F) << "point " << i;
    ASSERT_NEAR(read.y[j], cloud[i].y, 1e-6F) << "point " << i;
    ASSERT_NEAR(read.z[j], cloud[i].z, 1e-6F) << "point " << i;
    ASSERT_EQ(read.intensity[j], cloud[i].intensity) << "point " << i;
    ++j;
  }
  std::filesystem::remove(path);
}

INSTANTIATE_TEST_SUITE_P(Encodings, PcdPclTest,
                         ::testing::Values(Encoding::kAscii, Encoding::kBinary, Encoding::kBinaryCompressed),
                         [](const auto& p) {
                           switch (p.param) {
                             case Encoding::kAscii: return std::string("ascii");
                             case Encoding::kBinary: return std::string("binary");
                             default: return std::string("binary_compressed");
                           }
                         });

// A compressed file cut short, or with a flipped byte in its LZF data, is refused
// with the reason, never read past its buffers.
TEST(PcdPclDamageTest, DamagedCompressedFilesAreRefused) {
  const auto cloud = make_cloud(5000);
  const std::string path = temp_path("damaged");
  ASSERT_EQ(pcl::PCDWriter().writeBinaryCompressed(path, cloud), 0);
  std::ostringstream raw;
  raw << std::ifstream(path, std::ios::binary).rdbuf();
  const std::string contents = raw.str();
  std::filesystem::remove(path);
  const std::size_t data = contents.find("DATA binary_compressed\n") + 23;
  scan3d::PcdCloud read;
  std::string error;
  EXPECT_FALSE(scan3d::parse_pcd("cut.pcd", contents.substr(0, contents.size() - 100), read, error));
  EXPECT_NE(error.find("truncated file?"), std::string::npos) << error;
  // Every control byte position tried would take long; flip a run of bytes in the
  // middle of the LZF stream: either the stream breaks (refused) or it still decodes
  // to exactly the declared size (LZF has no checksum), never more.
  int refused = 0;
  for (std::size_t k = data + 8; k < contents.size(); k += 97) {
    std::string bad = contents;
    bad[k] = static_cast<char>(bad[k] ^ 0xE5);
    if (!scan3d::parse_pcd("flipped.pcd", bad, read, error)) {
      ++refused;
      EXPECT_NE(error.find("binary_compressed data"), std::string::npos) << error;
    }
  }
  EXPECT_GT(refused, 0);
}

// What STORE_DATA writes (scan3d::write_pcd) loads in PCL with the same points.
TEST(PcdPclWriteTest, PclLoadsWhatStoreDataWrites) {
  auto scan = std::make_unique<interfaces::Scan3dData>();
  scan->point_count = 1000;
  for (uint32_t i = 0; i < scan->point_count; ++i) {
    scan->x[i] = 0.01F * static_cast<float>(i);
    scan->y[i] = -1.0F;
    scan->z[i] = 0.5F;
    scan->intensity[i] = static_cast<float>(i % 100);
  }
  const std::string path = temp_path("out");
  std::string error;
  ASSERT_TRUE(scan3d::write_pcd(path, *scan, error)) << error;
  pcl::PointCloud<pcl::PointXYZI> loaded;
  ASSERT_EQ(pcl::io::loadPCDFile(path, loaded), 0);
  ASSERT_EQ(loaded.size(), scan->point_count);
  for (uint32_t i = 0; i < scan->point_count; ++i) {
    ASSERT_FLOAT_EQ(loaded[i].x, scan->x[i]);
    ASSERT_FLOAT_EQ(loaded[i].z, scan->z[i]);
    ASSERT_FLOAT_EQ(loaded[i].intensity, scan->intensity[i]);
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace rack::test
