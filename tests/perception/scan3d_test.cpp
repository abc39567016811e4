// Scan3D: the PCL pipeline on a synthetic cloud (a floor, two boxes, a ceiling, stray
// points), the range image, the PCD reader/writer (and its errors for malformed
// files), the assembly of 3-D scans from 2-D scans and a drive's position stream in
// every scan mode (a known wall and floor end up where they are), and the component
// in a real executor (ladar on a simulated drive; PCD playback with a malformed file;
// STORE_DATA; GET_RANGE_IMAGE).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sys/stat.h>
#include <unistd.h>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "../unit/test_support.h"
#include "common/pose2d.h"
#include "common/pose_series.h"
#include "common/scan3d_geometry.h"
#include "scan3d/scan3d_types.h"
#include "rack/interfaces/robot.h"
#include "rack/scan3d/pcd_file.h"
#include "rack/scan3d/scan3d_assembler.h"
#include "rack/scan3d/scan3d_pipeline.h"

namespace rack::test {
namespace {

using interfaces::Scan3dData;

struct Cloud {
  std::vector<float> x, y, z;
  void add(double px, double py, double pz) {
    x.push_back(static_cast<float>(px));
    y.push_back(static_cast<float>(py));
    z.push_back(static_cast<float>(pz));
  }
};

// Points on the surface of an axis-aligned box standing on the floor (sides and top).
void add_box(Cloud& c, double cx, double cy, double sx, double sy, double sz, double step) {
  for (double z = step; z <= sz + 1e-9; z += step) {
    for (double t = -sx / 2; t <= sx / 2 + 1e-9; t += step) {
      c.add(cx + t, cy - sy / 2, z);
      c.add(cx + t, cy + sy / 2, z);
    }
    for (double t = -sy / 2; t <= sy / 2 + 1e-9; t += step) {
      c.add(cx - sx / 2, cy + t, z);
      c.add(cx + sx / 2, cy + t, z);
    }
  }
  for (double u = -sx / 2; u <= sx / 2 + 1e-9; u += step) {
    for (double v = -sy / 2; v <= sy / 2 + 1e-9; v += step) c.add(cx + u, cy + v, sz);
  }
}

// A 8 m x 8 m floor with 1 cm noise, two boxes, a ceiling at 2.5 m, and stray points.
Cloud room(uint32_t seed) {
  Cloud c;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  for (double x = -4; x <= 4; x += 0.04) {
    for (double y = -4; y <= 4; y += 0.04) c.add(x, y, noise(rng));
  }
  add_box(c, 2.0, 1.0, 0.5, 0.5, 0.8, 0.03);
  add_box(c, -1.5, -2.0, 0.4, 0.6, 0.5, 0.03);
  // The ceiling as densely sampled as the floor after the voxel grid: statistical
  // outlier removal judges every point against the cloud's global mean spacing.
  for (double x = -4; x <= 4; x += 0.05) {
    for (double y = -4; y <= 4; y += 0.05) c.add(x, y, 2.5 + noise(rng));
  }
  c.add(3.3, -3.3, 1.7);  // stray points (dust, mixed pixels): alone in their neighbourhood
  c.add(-3.1, 3.6, 1.2);
  return c;
}

bool in_box(float x, float y, double cx, double cy, double sx, double sy) {
  return std::fabs(x - cx) <= sx / 2 + 0.06 && std::fabs(y - cy) <= sy / 2 + 0.06;
}

TEST(Scan3dPipelineTest, FindsTheFloorAndTypesBoxesAndCeiling) {
  const Cloud c = room(1);
  scan3d::Scan3dPipeline pipeline;
  scan3d::PipelineOptions o;
  o.voxel_size = 0.05;
  o.ceiling_height = 2.0;
  auto out = std::make_unique<Scan3dData>();
  pipeline.process(c.x.data(), c.y.data(), c.z.data(), nullptr, c.x.size(), o, *out);

  EXPECT_EQ(out->raw_points, c.x.size());
  ASSERT_GT(out->point_count, 1000U);
  EXPECT_LT(out->point_count, c.x.size());  // downsampled
  ASSERT_EQ(out->ground_valid, 1);
  EXPECT_GT(out->ground_c, 0.999F);         // the plane is the floor: normal up,
  EXPECT_NEAR(out->ground_d, 0.0F, 0.02F);  // through z = 0
  uint32_t floor = 0, floor_ground = 0, box = 0, box_object = 0, ceiling = 0, ceiling_typed = 0;
  for (uint32_t i = 0; i < out->point_count; ++i) {
    const float x = out->x[i], y = out->y[i], z = out->z[i];
    const uint8_t t = out->type[i];
    EXPECT_FALSE(std::fabs(x - 3.3F) < 0.05F && std::fabs(y + 3.3F) < 0.05F && std::fabs(z - 1.7F) < 0.05F)
        << "a stray point survived the outlier removal";
    if (std::fabs(z) < 0.02F) {
      ++floor;
      floor_ground += t == interfaces::kScanPointGround;
    } else if (z > 0.1F && z < 1.0F && (in_box(x, y, 2.0, 1.0, 0.5, 0.5) || in_box(x, y, -1.5, -2.0, 0.4, 0.6))) {
      ++box;
      box_object += t == interfaces::kScanPointObstacle;
    } else if (z > 2.4F) {
      ++ceiling;
      ceiling_typed += t == interfaces::kScanPointCeiling;
    }
  }
  EXPECT_GT(floor, 10000U);
  EXPECT_GE(floor_ground, floor * 99 / 100) << "floor points typed ground";
  EXPECT_GT(box, 300U);
  EXPECT_EQ(box_object, box) << "every box point above the floor tolerance is an object";
  EXPECT_GT(ceiling, 1000U);
  EXPECT_EQ(ceiling_typed, ceiling);
  EXPECT_EQ(out->ground_points + out->object_points + out->ceiling_points, out->point_count);
  EXPECT_GT(out->process_ms, 0.0F);
}

TEST(Scan3dPipelineTest, BoundsThePointCountAndLeavesPointsUntypedWithoutGround) {
  Cloud c;
  for (int i = 0; i < 20000; ++i) c.add(0.001 * i, 1.0 + 0.0001 * (i % 97), 1.5);  // a line in the air
  scan3d::Scan3dPipeline pipeline;
  scan3d::PipelineOptions o;
  o.voxel_size = 0.0;
  o.outlier_neighbours = 0;
  o.max_points = 1000;
  auto out = std::make_unique<Scan3dData>();
  pipeline.process(c.x.data(), c.y.data(), c.z.data(), nullptr, c.x.size(), o, *out);
  EXPECT_EQ(out->point_count, 1000U);
  EXPECT_EQ(out->ground_valid, 0);
  for (uint32_t i = 0; i < out->point_count; ++i) ASSERT_EQ(out->type[i], interfaces::kScanPointNormal);
  // An empty cloud is no failure either.
  pipeline.process(nullptr, nullptr, nullptr, nullptr, 0, o, *out);
  EXPECT_EQ(out->point_count, 0U);
}

TEST(Scan3dPipelineTest, RejectsBadOptions) {
  scan3d::PipelineOptions o;
  o.voxel_size = 1e-5;
  EXPECT_THROW(scan3d::validate(o), std::invalid_argument);
  o = {};
  o.max_points = interfaces::kScan3dMaxPoints + 1;
  EXPECT_THROW(scan3d::validate(o), std::invalid_argument);
  EXPECT_NO_THROW(scan3d::validate(scan3d::PipelineOptions{}));
}

TEST(Scan3dPipelineTest, RangeImageLooksOutFromTheSensor) {
  auto scan = std::make_unique<Scan3dData>();
  uint32_t n = 0;
  const auto patch = [&](double cx, double cy, double cz) {
    for (int i = -3; i <= 3; ++i) {
      for (int j = -3; j <= 3; ++j) {
        scan->x[n] = static_cast<float>(cx);
        scan->y[n] = static_cast<float>(cy + 0.02 * i);
        scan->z[n] = static_cast<float>(cz + 0.02 * j);
        ++n;
      }
    }
  };
  patch(3.0, 1.0, 0.5);   // left, range ~3.16 from the sensor at (0, 0, 0.5)
  patch(5.0, -1.0, 0.5);  // right, range ~5.10
  patch(4.0, 0.0, 2.5);   // up, range ~4.47
  scan->point_count = n;
  auto image = std::make_unique<interfaces::Scan3dRangeImage>();
  std::string error;
  ASSERT_TRUE(scan3d::Scan3dPipeline::range_image(*scan, 0.0, 0.0, 0.5, 0.5 * M_PI / 180.0, *image, error)) << error;
  ASSERT_GT(image->width, 10U);
  ASSERT_GT(image->height, 10U);
  // Where each patch landed (the pixel nearest to its range).
  const auto find = [&](double range, uint32_t& col, uint32_t& row) {
    double best = 1e9;
    for (uint32_t r = 0; r < image->height; ++r) {
      for (uint32_t c = 0; c < image->width; ++c) {
        const double d = std::fabs(image->range[r * image->width + c] - range);
        if (image->range[r * image->width + c] > 0 && d < best) {
          best = d;
          col = c;
          row = r;
        }
      }
    }
    return best < 0.05;
  };
  uint32_t lc = 0, lr = 0, rc = 0, rr = 0, uc = 0, ur = 0;
  ASSERT_TRUE(find(std::hypot(3.0, 1.0), lc, lr));
  ASSERT_TRUE(find(std::hypot(5.0, 1.0), rc, rr));
  ASSERT_TRUE(find(std::hypot(4.0, 2.0), uc, ur));
  EXPECT_LT(lc, rc) << "column 0 is the left";
  EXPECT_LT(ur, lr) << "row 0 is the top";
  // The corner angles say the same: column 0 looks left of the left patch (azimuth 18 deg).
  EXPECT_GE(image->angle_left, std::atan2(1.0, 3.0) - 0.02);
  EXPECT_GE(image->angle_top, std::atan2(2.0, 4.0) - 0.02);
  // Too fine for the payload: a clear error.
  EXPECT_FALSE(scan3d::Scan3dPipeline::range_image(*scan, 0.0, 0.0, 0.5, 0.01 * M_PI / 180.0, *image, error));
  EXPECT_NE(error.find("between 0.2 and 57 degrees"), std::string::npos) << error;
  // A scan all round the sensor at 0.25 degrees: 1440 x 720 pixels, more than the payload holds.
  for (uint32_t i = 0; i < 360; ++i) {
    const double a = i * M_PI / 180.0;
    scan->x[i] = static_cast<float>(3.0 * std::cos(a));
    scan->y[i] = static_cast<float>(3.0 * std::sin(a));
    scan->z[i] = static_cast<float>(i % 2 ? 3.5 : -2.5);
  }
  scan->point_count = 360;
  EXPECT_FALSE(scan3d::Scan3dPipeline::range_image(*scan, 0.0, 0.0, 0.5, 0.25 * M_PI / 180.0, *image, error));
  EXPECT_NE(error.find("coarser"), std::string::npos) << error;
}

// ---------------------------------------------------------------------------
// PCD files.

std::string temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("rack_scan3d_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

const char* kHeader =
    "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
    "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n";

TEST(PcdFileTest, ReadsAsciiAndBinaryAndWritesWhatItReads) {
  scan3d::PcdCloud cloud;
  std::string error;
  ASSERT_TRUE(scan3d::parse_pcd("a.pcd", std::string(kHeader) + "1 2 3 10\n4 5 6 20\nnan nan nan 0\n", cloud, error))
      << error;
  ASSERT_EQ(cloud.size(), 2U);  // the NaN point is left out
  EXPECT_EQ(cloud.non_finite, 1U);
  EXPECT_FLOAT_EQ(cloud.y[1], 5.0F);
  EXPECT_FLOAT_EQ(cloud.intensity[1], 20.0F);

  auto scan = std::make_unique<Scan3dData>();
  scan->point_count = 3;
  for (uint32_t i = 0; i < 3; ++i) {
    scan->x[i] = 1.5F * static_cast<float>(i);
    scan->y[i] = -2.0F;
    scan->z[i] = 0.25F;
    scan->intensity[i] = 7.0F;
    scan->type[i] = interfaces::kScanPointGround;
  }
  const std::string path = temp_dir("rw") + "/scan.pcd";
  ASSERT_TRUE(scan3d::write_pcd(path, *scan, error)) << error;
  ASSERT_TRUE(scan3d::read_pcd(path, cloud, error)) << error;  // binary, with a U1 field
  ASSERT_EQ(cloud.size(), 3U);
  EXPECT_FLOAT_EQ(cloud.x[2], 3.0F);
  EXPECT_FLOAT_EQ(cloud.y[0], -2.0F);
  EXPECT_FLOAT_EQ(cloud.intensity[2], 7.0F);
  EXPECT_FALSE(scan3d::write_pcd("/nonexistent/dir/x.pcd", *scan, error));
  EXPECT_NE(error.find("/nonexistent/dir/x.pcd"), std::string::npos) << error;
}

struct BadPcd {
  const char* what;
  std::string text;
  const char* expect;  // in the error message
};

const std::string kCompressedHeader = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary_compressed\n";
// binary_compressed's two sizes (compressed, raw), little-endian.
std::string sizes(uint32_t packed, uint32_t raw) {
  std::string s(8, '\0');
  std::memcpy(s.data(), &packed, 4);
  std::memcpy(s.data() + 4, &raw, 4);
  return s;
}

TEST(PcdFileTest, RejectsMalformedFilesWithLineAndReason) {
  const std::string h(kHeader);
  const std::vector<BadPcd> cases = {
      {"empty", "", "a.pcd: header ends without a DATA line"},
      {"size count", "VERSION 0.7\nFIELDS x y z\nSIZE 4 4\n", "a.pcd:3: SIZE has 2 entries, FIELDS has 3"},
      {"bad type", "FIELDS x y z\nSIZE 4 4 4\nTYPE F Q F\n", "a.pcd:3: TYPE of field 'y' is 'Q'"},
      {"unknown key", "FIELDS x y z\nCOLOR red\n", "a.pcd:2: unknown header keyword 'COLOR'"},
      {"no z", "FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2\n", "a.pcd:5: FIELDS must include x, y and z"},
      {"points", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 3\nDATA ascii\n",
       "POINTS 3 is not WIDTH x HEIGHT = 2"},
      {"bad number", h + "1 2 3 4\n1 abc 3 4\n", "a.pcd:13: point 1, field 'y': 'abc' is not a number"},
      {"short line", h + "1 2 3 4\n1 2 3\n", "a.pcd:13: point 1 has 3 values, FIELDS need 4"},
      {"too few", h + "1 2 3 4\n", "file ends after 1 of 3 points"},
      {"too many", h + "1 2 3 4\n1 2 3 4\n1 2 3 4\n1 2 3 4\n", "a.pcd:15: more points than POINTS 3"},
      {"binary short", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 10\nDATA binary\n" + std::string(20, '\0'),
       "binary data holds 20 bytes, the header needs 10 points x 12 bytes = 120"},
      {"compressed, no sizes", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary_compressed\n",
       "binary_compressed data: 0 bytes, no size header"},
      {"compressed, raw size", kCompressedHeader + sizes(4, 24) + std::string(4, '\0'),
       "raw size 24, the header needs 1 points x 12 bytes = 12"},
      {"compressed, truncated", kCompressedHeader + sizes(40, 12) + std::string(4, '\0'),
       "4 bytes after the sizes, 40 declared"},
      // A back reference (control byte 0x20: 3 bytes, 1 behind) before any output.
      {"compressed, bad reference", kCompressedHeader + sizes(2, 12) + std::string("\x20\x00", 2),
       "a back reference points before the start of the data"},
      // A literal run of 32 bytes (control 31) into a 12-byte cloud.
      {"compressed, overflow", kCompressedHeader + sizes(33, 12) + std::string(1, '\x1f') + std::string(32, 'a'),
       "decompresses to more than the declared size"},
      {"compressed, lie",
       "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 100000\nDATA binary_compressed\n" + sizes(2, 1200000) +
           std::string(2, '\0'),
       "more than LZF can expand"},
      {"float size", "FIELDS x y z\nSIZE 4 2 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
       "field 'y': TYPE F with SIZE 2"},
  };
  for (const auto& c : cases) {
    scan3d::PcdCloud cloud;
    std::string error;
    EXPECT_FALSE(scan3d::parse_pcd("a.pcd", c.text, cloud, error)) << c.what;
    EXPECT_NE(error.find(c.expect), std::string::npos) << c.what << ": got '" << error << "'";
  }
  scan3d::PcdCloud cloud;
  std::string error;
  EXPECT_FALSE(scan3d::read_pcd("/nonexistent.pcd", cloud, error));
  EXPECT_NE(error.find("/nonexistent.pcd: cannot open"), std::string::npos) << error;
}

// Issue 17: the point size (sum of SIZE x COUNT) wrapped to 0 in 32 bits, so the
// data check passed with no data and x was read 4 GB past the buffer (SIGSEGV took
// rackd down); WIDTH x HEIGHT without POINTS was unbounded. Now every size is 64-bit
// and held to a documented limit before anything is allocated or read.
TEST(PcdFileTest, OverflowingSizesAreRefusedBeforeTheyAreUsed) {
  std::string names, sizes_line, types, counts;
  for (int i = 0; i < 1074; ++i) {
    names += " f" + std::to_string(i);
    sizes_line += " 4";
    types += " F";
    counts += i < 1073 ? " 1000000" : " 741821";
  }
  const std::string wraps = "FIELDS" + names + " x y z\nSIZE" + sizes_line + " 4 4 4\nTYPE" + types + " F F F\nCOUNT" +
                            counts + " 1 1 1\nWIDTH 1\nHEIGHT 1\nDATA binary\n";
  std::string few_names, few_sizes, few_types, few_counts;
  for (int i = 0; i < 10; ++i) {
    few_names += " f" + std::to_string(i);
    few_sizes += " 8";
    few_types += " F";
    few_counts += " 1000000";
  }
  const std::string wide = "FIELDS x y z" + few_names + "\nSIZE 4 4 4" + few_sizes + "\nTYPE F F F" + few_types +
                           "\nCOUNT 1 1 1" + few_counts + "\nWIDTH 1\nDATA binary\n";
  const std::vector<BadPcd> cases = {
      {"point size wraps to 0", wraps, "a.pcd:1: FIELDS names 1077 fields, more than the limit of 1000"},
      {"wide point", wide,
       "a.pcd:6: a point of these FIELDS, SIZE and COUNT takes 80000012 bytes, more than the limit"},
      {"width x height", "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 1000000000\nHEIGHT 1000000000\nDATA binary\n",
       "a.pcd:4: WIDTH 1000000000 is more than the limit of 10000000 points"},
      {"product", "FIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 10000000\nHEIGHT 10000000\nDATA binary\n",
       "a.pcd:6: WIDTH x HEIGHT = 100000000000000 points, more than the limit of 10000000"},
      {"points", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 18446744073709551615\nDATA ascii\n",
       "a.pcd:5: POINTS 18446744073709551615 is more than the limit"},
      {"huge ascii claim", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 9000000\nDATA ascii\n1 2 3\n",
       "file ends after 1 of 9000000 points"},
  };
  for (const auto& c : cases) {
    scan3d::PcdCloud cloud;
    std::string error;
    EXPECT_FALSE(scan3d::parse_pcd("a.pcd", c.text, cloud, error)) << c.what;
    EXPECT_NE(error.find(c.expect), std::string::npos) << c.what << ": got '" << error << "'";
    EXPECT_LE(cloud.x.capacity(), 16u) << c.what << ": reserved for what the header claimed";
  }
}

TEST(PcdFileTest, FifosDevicesDirectoriesAndHugeFilesAreRefusedWithoutWaiting) {
  const std::string dir = temp_dir("hostile");
  const std::string fifo = dir + "/fifo.pcd";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string big = dir + "/big.pcd";
  std::ofstream(big).close();
  std::filesystem::resize_file(big, scan3d::kMaxPcdFileBytes + 1);
  test::Watchdog watchdog(std::chrono::seconds(20));
  const std::pair<std::string, std::string> cases[] = {
      {fifo, fifo + ": the PCD file is a FIFO, not a regular file"},
      {"/dev/zero", "/dev/zero: the PCD file is a character device"},
      {dir, dir + ": the PCD file is a directory"},
      {big, big + ": the PCD file has 256.0 MiB, more than the limit of 256 MiB"},
  };
  for (const auto& [path, expect] : cases) {
    scan3d::PcdCloud cloud;
    std::string error;
    EXPECT_FALSE(scan3d::read_pcd(path, cloud, error)) << path;
    EXPECT_NE(error.find(expect), std::string::npos) << error;
  }
  std::filesystem::remove_all(dir);
}

// ---------------------------------------------------------------------------
// Assembly: 2-D scans of a room (a wall at x = 3 m, the floor) taken while the drive
// turns at 1 rad/s; every beam is rendered at its own time with the exact angle, so a
// beam placed with the wrong angle would land off the wall or the floor.

constexpr double kWallX = 3.0;

// The range along a beam from the ladar's centre to the wall or the floor (0: neither).
double room_range(const components::Scan3dMount& m, double theta, double bearing) {
  const components::Vec3 d = components::scan3d_direction(m.mode, theta, bearing);
  double t = 1e9;
  if (d.x > 1e-6) t = std::min(t, (kWallX - m.x) / d.x);
  if (d.z < -1e-6) t = std::min(t, -m.z / d.z);
  return t < 20.0 ? t : 0.0;
}

// An empty 2-D scan of 181 beams over the half circle ahead, 1 degree apart, up to
// 20 m, taking 25 ms (as a real scanner's mirror turns); the tests fill in the ranges.
std::unique_ptr<interfaces::LadarData> half_circle_scan() {
  auto scan = std::make_unique<interfaces::LadarData>();
  scan->beam_count = 181;
  scan->start_angle = static_cast<float>(-M_PI / 2);
  scan->angle_step = static_cast<float>(M_PI / 180.0);
  scan->max_range = 20.0F;
  scan->duration_ns = 25'000'000;
  return scan;
}

class Scan3dAssemblyTest : public ::testing::TestWithParam<uint8_t> {};

TEST_P(Scan3dAssemblyTest, AKnownWallAndFloorEndUpWhereTheyAre) {
  components::Scan3dMount mount{GetParam(), 0.2, 0.0, 0.5};
  scan3d::Scan3dAssembler a(200000);
  scan3d::AssemblerConfig cfg;
  cfg.mount = mount;
  a.set_config(cfg);
  a.reset();
  // Drive: from -0.6 rad at t0, 1 rad/s, sampled every 10 ms (2 ms of jitter).
  const int64_t t0 = 1'000'000'000'000;
  const auto angle = [&](int64_t t) { return -0.6 + 1.0 * static_cast<double>(t - t0) * 1e-9; };
  std::mt19937 rng(4);
  std::uniform_int_distribution<int64_t> jitter(0, 2'000'000);
  for (int64_t t = t0; t <= t0 + 1'300'000'000; t += 10'000'000) {
    const int64_t ts = t + jitter(rng);
    a.add_drive_sample(ts, angle(ts));
  }
  // 2-D scans every 40 ms, each taking 25 ms (as a real scanner's mirror turns).
  auto scan = half_circle_scan();
  uint32_t scans = 0;
  for (int64_t t = t0 + 5'000'000; t + scan->duration_ns <= t0 + 1'200'000'000; t += 40'000'000) {
    for (uint32_t b = 0; b < scan->beam_count; ++b) {
      const int64_t tb = t + scan->duration_ns * b / (scan->beam_count - 1);
      const double bearing = scan->start_angle + b * static_cast<double>(scan->angle_step);
      scan->range[b] = static_cast<float>(room_range(mount, angle(tb), bearing));
    }
    ASSERT_EQ(a.add_scan(*scan, t), scan3d::AddStatus::kAdded);
    ++scans;
  }
  EXPECT_EQ(a.scans(), scans);
  ASSERT_GT(a.size(), 1000U);
  uint32_t wall = 0, floor = 0;
  for (uint32_t i = 0; i < a.size(); ++i) {
    const bool on_wall = std::fabs(a.x()[i] - kWallX) < 0.01;
    const bool on_floor = std::fabs(a.z()[i]) < 0.01;
    ASSERT_TRUE(on_wall || on_floor) << "point " << i << " at (" << a.x()[i] << ", " << a.y()[i] << ", " << a.z()[i]
                                     << ") is on neither the wall nor the floor";
    wall += on_wall;
    floor += on_floor;
  }
  EXPECT_GT(wall, 100U);
  EXPECT_GT(floor, 100U);  // every mode sees the floor: pitch and yaw ahead, roll to the sides
}

INSTANTIATE_TEST_SUITE_P(Modes, Scan3dAssemblyTest,
                         ::testing::Values(interfaces::kScan3dModeRoll, interfaces::kScan3dModePitch,
                                           interfaces::kScan3dModeYaw),
                         [](const ::testing::TestParamInfo<uint8_t>& i) {
                           return std::string(i.param == interfaces::kScan3dModeRoll    ? "Roll"
                                              : i.param == interfaces::kScan3dModePitch ? "Pitch"
                                                                                        : "Yaw");
                         });

TEST(Scan3dAssemblerTest, WaitsForTheDriveAndSkipsWhatItCannotPlace) {
  scan3d::Scan3dAssembler a(1000);
  auto scan = std::make_unique<interfaces::LadarData>();
  scan->beam_count = 3;
  scan->angle_step = 0.1F;
  scan->max_range = 10.0F;
  scan->range[0] = scan->range[1] = scan->range[2] = 2.0F;
  scan->duration_ns = 10'000'000;
  EXPECT_EQ(a.add_scan(*scan, 100), scan3d::AddStatus::kWaitForDrive);  // no drive sample yet
  a.add_drive_sample(1'000'000'000, 0.1);
  a.add_drive_sample(1'020'000'000, 0.2);
  EXPECT_EQ(a.add_scan(*scan, 500'000'000), scan3d::AddStatus::kNoDriveAngle);    // before the history
  EXPECT_EQ(a.add_scan(*scan, 1'015'000'000), scan3d::AddStatus::kWaitForDrive);  // ends after the newest sample
  EXPECT_EQ(a.add_scan(*scan, 1'005'000'000), scan3d::AddStatus::kAdded);
  EXPECT_EQ(a.size(), 3U);
  scan->range[0] = scan->range[1] = scan->range[2] = 0.0F;
  EXPECT_EQ(a.add_scan(*scan, 1'005'000'000), scan3d::AddStatus::kEmpty);
  scan->beam_count = 0;
  EXPECT_EQ(a.add_scan(*scan, 1'005'000'000), scan3d::AddStatus::kMalformed);
  scan->beam_count = interfaces::kLadarMaxBeams + 1;
  EXPECT_EQ(a.add_scan(*scan, 1'005'000'000), scan3d::AddStatus::kMalformed);
  EXPECT_EQ(a.size(), 3U);
}

// ---------------------------------------------------------------------------
// Motion compensation: the robot drives straight at 0.5 m/s towards a flat wall 4 m
// ahead of where it starts while the drive pitches the ladar from -0.6 to 0.6 rad at
// 1 rad/s (a 1.2 s sweep: 0.6 m of travel). Each beam is rendered from where the
// robot is at its time. The odometry frame is deliberately not the robot's start
// frame (offset and turned), so the rotation is exercised too.

struct DrivingSweep {
  static constexpr double kSpeed = 0.5;      // m/s along the robot's x
  static constexpr double kWallAhead = 4.0;  // m from the start pose's origin
  static constexpr int64_t kT0 = 2'000'000'000'000;
  components::Scan3dMount mount{interfaces::kScan3dModePitch, 0.2, 0.0, 0.5};
  components::Pose2d start{10.0, -5.0, 0.7};  // in the odometry frame

  static double travelled(int64_t t) { return kSpeed * static_cast<double>(t - kT0) * 1e-9; }
  static double angle(int64_t t) { return -0.6 + 1.0 * static_cast<double>(t - kT0) * 1e-9; }
  components::Pose2d pose(int64_t t) const {
    return components::compose(start, components::Pose2d{travelled(t), 0.0, 0.0});
  }
  // Range from the ladar's centre to the wall (perpendicular to the robot's x) or the floor.
  double range(int64_t t, double bearing) const {
    const components::Vec3 d = components::scan3d_direction(mount.mode, angle(t), bearing);
    double r = 1e9;
    if (d.x > 1e-6) r = std::min(r, (kWallAhead - travelled(t) - mount.x) / d.x);
    if (d.z < -1e-6) r = std::min(r, -mount.z / d.z);
    return r < 20.0 ? r : 0.0;
  }
  // Feeds drive samples (every 10 ms), poses (every 20 ms) and 2-D scans (every 40 ms,
  // 25 ms each) of one sweep; the time of the last scan's end.
  int64_t run(scan3d::Scan3dAssembler& a) const {
    for (int64_t t = kT0; t <= kT0 + 1'300'000'000; t += 10'000'000) a.add_drive_sample(t, angle(t));
    for (int64_t t = kT0 - 100'000'000; t <= kT0 + 1'300'000'000; t += 20'000'000) (void)a.add_pose(t, pose(t));
    auto scan = half_circle_scan();
    int64_t end = 0;
    for (int64_t t = kT0 + 5'000'000; t + scan->duration_ns <= kT0 + 1'200'000'000; t += 40'000'000) {
      for (uint32_t b = 0; b < scan->beam_count; ++b) {
        const int64_t tb = t + scan->duration_ns * b / (scan->beam_count - 1);
        scan->range[b] = static_cast<float>(range(tb, scan->start_angle + b * static_cast<double>(scan->angle_step)));
      }
      EXPECT_EQ(a.add_scan(*scan, t), scan3d::AddStatus::kAdded);
      end = t + scan->duration_ns;
    }
    return end;
  }
};

struct Band {
  uint32_t n = 0;
  double min = 1e9, max = -1e9, sum = 0.0;
  [[nodiscard]] double thickness() const { return max - min; }
  [[nodiscard]] double mean() const { return sum / n; }
};
// The wall's points (above the floor): their spread along x.
Band wall_band(const scan3d::Scan3dAssembler& a) {
  Band b;
  for (uint32_t i = 0; i < a.size(); ++i) {
    if (a.z()[i] < 0.05F) continue;  // the floor
    const double x = a.x()[i];
    ++b.n;
    b.min = std::min(b.min, x);
    b.max = std::max(b.max, x);
    b.sum += x;
  }
  return b;
}

TEST(Scan3dMotionTest, OdometryKeepsAWallAheadThinWhileTheRobotDrives) {
  const DrivingSweep s;
  scan3d::AssemblerConfig cfg;
  cfg.mount = s.mount;

  scan3d::Scan3dAssembler plain(200000);
  plain.set_config(cfg);
  plain.reset();
  (void)s.run(plain);
  EXPECT_FALSE(plain.to_end_frame()) << "without compensation the points stay where they are";
  const Band smeared = wall_band(plain);

  cfg.compensate_motion = true;
  scan3d::Scan3dAssembler a(200000);
  a.set_config(cfg);
  a.reset();
  const int64_t end = s.run(a);
  EXPECT_EQ(a.last_time_ns(), end);
  ASSERT_TRUE(a.to_end_frame());
  EXPECT_FALSE(a.to_end_frame()) << "only once per sweep";
  const Band thin = wall_band(a);

  ASSERT_GT(smeared.n, 300U);
  ASSERT_EQ(thin.n, smeared.n);
  // Without: each beam where the robot was at its time, spread over the 0.6 m driven.
  EXPECT_GT(smeared.thickness(), 0.20) << "the scenario must smear without compensation";
  // With: the wall where it is from the robot at the sweep's end.
  EXPECT_LT(thin.thickness(), 0.03);
  EXPECT_NEAR(thin.mean(), DrivingSweep::kWallAhead - DrivingSweep::travelled(end), 0.01);
  std::printf("wall thickness: %.3f m without odometry, %.4f m with (%u points)\n", smeared.thickness(),
              thin.thickness(), thin.n);
  // Every point is on the wall (as seen from the end pose) or on the floor.
  const double wall_x = DrivingSweep::kWallAhead - DrivingSweep::travelled(end);
  for (uint32_t i = 0; i < a.size(); ++i) {
    ASSERT_TRUE(std::fabs(a.x()[i] - wall_x) < 0.01 || std::fabs(a.z()[i]) < 0.01)
        << "point " << i << " at (" << a.x()[i] << ", " << a.y()[i] << ", " << a.z()[i] << ")";
  }
}

TEST(Scan3dMotionTest, WaitsForAPoseAfterTheScanAndSkipsScansOlderThanThePoses) {
  scan3d::Scan3dAssembler a(1000);
  scan3d::AssemblerConfig cfg;
  cfg.compensate_motion = true;
  a.set_config(cfg);
  auto scan = std::make_unique<interfaces::LadarData>();
  scan->beam_count = 3;
  scan->angle_step = 0.1F;
  scan->max_range = 10.0F;
  scan->range[0] = scan->range[1] = scan->range[2] = 2.0F;
  scan->duration_ns = 10'000'000;
  a.add_drive_sample(1'000'000'000, 0.1);
  a.add_drive_sample(1'100'000'000, 0.2);
  EXPECT_EQ(a.add_scan(*scan, 1'005'000'000), scan3d::AddStatus::kWaitForPose);  // no pose yet
  EXPECT_TRUE(a.add_pose(1'010'000'000, components::Pose2d{1.0, 0.0, 0.0}));
  EXPECT_FALSE(a.add_pose(1'010'000'000, components::Pose2d{2.0, 0.0, 0.0})) << "not newer: ignored";
  EXPECT_TRUE(a.add_pose(1'030'000'000, components::Pose2d{1.2, 0.0, 0.0}));
  EXPECT_EQ(a.add_scan(*scan, 1'005'000'000), scan3d::AddStatus::kNoPose);       // starts before the poses
  EXPECT_EQ(a.add_scan(*scan, 1'025'000'000), scan3d::AddStatus::kWaitForPose);  // ends after the newest
  EXPECT_EQ(a.add_scan(*scan, 1'015'000'000), scan3d::AddStatus::kAdded);
  EXPECT_EQ(a.size(), 3U);
  EXPECT_TRUE(a.to_end_frame());
  a.reset();
  EXPECT_FALSE(a.to_end_frame()) << "nothing assembled";
}

TEST(Scan3dMotionTest, PosesAreInterpolatedTheShortWayRound) {
  components::PoseSeries<4> p;
  components::Pose2d out;
  EXPECT_EQ(p.pose_at(0, out), components::SeriesLookup::kEmpty);
  EXPECT_TRUE(p.push(100, components::Pose2d{0.0, 0.0, 3.0}));
  EXPECT_TRUE(p.push(200, components::Pose2d{1.0, 2.0, -3.0}));  // across +-pi
  ASSERT_EQ(p.pose_at(150, out), components::SeriesLookup::kOk);
  EXPECT_NEAR(out.x, 0.5, 1e-12);
  EXPECT_NEAR(out.y, 1.0, 1e-12);
  EXPECT_NEAR(std::fabs(out.phi), M_PI, 1e-9);
  EXPECT_EQ(p.pose_at(99, out), components::SeriesLookup::kTooOld);
  EXPECT_EQ(p.pose_at(201, out), components::SeriesLookup::kTooNew) << "no extrapolation";
  for (int64_t t = 300; t <= 600; t += 100) EXPECT_TRUE(p.push(t, components::Pose2d{}));
  EXPECT_EQ(p.size(), 4U);  // a ring: the oldest went
  EXPECT_EQ(p.oldest_time(), 300);
  EXPECT_EQ(p.pose_at(250, out), components::SeriesLookup::kTooOld);
}

}  // namespace
}  // namespace rack::test
