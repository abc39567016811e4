// Occupancy maps: the shipped map loads with the geometry its YAML describes, rays
// hit its walls where they are drawn, and every kind of bad map file is rejected
// with the file and the line or byte offset.
#include "rack/maps/occupancy_map.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include "hostile_files.h"

namespace rack::maps {
namespace {

namespace fs = std::filesystem;

const std::string kOffice = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";

class OccupancyMapTest : public ::testing::Test {
 protected:
  OccupancyMapTest() {
    dir_ = fs::temp_directory_path() / ("rack-map-test-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  ~OccupancyMapTest() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& content) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << content;
    return p.string();
  }
  // A valid YAML naming `image`, with `extra` lines appended.
  std::string yaml(const std::string& image, const std::string& extra = "") {
    return write("map.yaml", "image: " + image +
                                 "\nresolution: 0.1\norigin: [1.0, 2.0, 0.0]\nnegate: 0\n"
                                 "occupied_thresh: 0.65\nfree_thresh: 0.196\n" +
                                 extra);
  }
  // Expects a failed load with an error whose text contains every word.
  static void expect_error(const LoadMapResult& r, std::initializer_list<std::string> words) {
    ASSERT_FALSE(r.ok());
    const std::string text = r.error_text();
    for (const auto& w : words) EXPECT_NE(text.find(w), std::string::npos) << "'" << w << "' not in:\n" << text;
  }

  fs::path dir_;
};

TEST_F(OccupancyMapTest, ShippedOfficeMapLoadsWithItsGeometry) {
  const LoadMapResult r = load_map(kOffice);
  ASSERT_TRUE(r.ok()) << r.error_text();
  const OccupancyMap& m = *r.map;
  EXPECT_EQ(m.width(), 500);
  EXPECT_EQ(m.height(), 340);
  EXPECT_DOUBLE_EQ(m.resolution(), 0.05);
  EXPECT_DOUBLE_EQ(m.origin_x(), -0.5);
  // The corridor is free, the walls occupied, the band outside unknown.
  EXPECT_EQ(m.state_at(12.0, 8.0), CellState::kFree);
  EXPECT_EQ(m.state_at(12.0, 10.0), CellState::kOccupied);
  EXPECT_EQ(m.state_at(2.0, 2.0), CellState::kOccupied);  // the table in room A
  EXPECT_EQ(m.state_at(-0.3, 8.0), CellState::kUnknown);
  EXPECT_EQ(m.state_at(100.0, 8.0), CellState::kUnknown);  // outside the grid
  EXPECT_GT(m.free_cell_count(), 100000u);
}

TEST_F(OccupancyMapTest, RaysHitTheShippedMapsWallsWhereTheyAreDrawn) {
  const LoadMapResult r = load_map(kOffice);
  ASSERT_TRUE(r.ok()) << r.error_text();
  const OccupancyMap& m = *r.map;
  constexpr double kPi = std::numbers::pi;
  // From the corridor's centre line: the walls are at y = 6 and 10, 0.1 m thick.
  RayHit up = m.cast_ray(12.0, 8.0, kPi / 2, 10.0);
  ASSERT_TRUE(up.hit);
  EXPECT_NEAR(up.range, 1.95, 0.051);
  RayHit down = m.cast_ray(12.0, 8.0, -kPi / 2, 10.0);
  ASSERT_TRUE(down.hit);
  EXPECT_NEAR(down.range, 1.95, 0.051);
  // East along the corridor: the outer wall at x = 24 (the bin is at y = 6.8, off this line).
  RayHit east = m.cast_ray(12.0, 8.0, 0.0, 30.0);
  ASSERT_TRUE(east.hit);
  EXPECT_NEAR(east.range, 11.95, 0.051);
  // Diagonal: a 135-degree ray meets the north wall (y = 9.95) at x = 10.05, between
  // doors, after 1.95 * sqrt(2). (At 45 degrees it would pass through the door at 13-14.2.)
  RayHit diag = m.cast_ray(12.0, 8.0, 3 * kPi / 4, 10.0);
  ASSERT_TRUE(diag.hit);
  EXPECT_NEAR(diag.range, 1.95 * std::numbers::sqrt2, 0.08);
  // Shorter than the wall: no hit, the range is the maximum.
  RayHit short_ray = m.cast_ray(12.0, 8.0, kPi / 2, 1.0);
  EXPECT_FALSE(short_ray.hit);
  EXPECT_FLOAT_EQ(short_ray.range, 1.0F);
  // Through a door (x = 3.0 .. 4.2 in the south wall) into room A and onto its south wall.
  RayHit door = m.cast_ray(3.6, 8.0, -kPi / 2, 20.0);
  ASSERT_TRUE(door.hit);
  EXPECT_NEAR(door.range, 7.95, 0.051);
  // Inside a wall: a hit at 0.
  RayHit inside = m.cast_ray(12.0, 10.0, 0.0, 5.0);
  EXPECT_TRUE(inside.hit);
  EXPECT_FLOAT_EQ(inside.range, 0.0F);
}

TEST_F(OccupancyMapTest, RotatedOriginIsHonoured) {
  // A 10x10 free map of 1 m cells with one occupied cell at (5, 0), rotated 90 deg:
  // the map's x axis points north.
  std::vector<float> occ(100, 0.0F);
  occ[5] = 1.0F;
  const OccupancyMap m(10, 10, 1.0, 0.0, 0.0, std::numbers::pi / 2, occ);
  EXPECT_EQ(m.state_at(-0.5, 5.5), CellState::kOccupied);
  EXPECT_EQ(m.state_at(5.5, 0.5), CellState::kUnknown);  // that side is outside
  const RayHit hit = m.cast_ray(-0.5, 0.5, std::numbers::pi / 2, 20.0);
  ASSERT_TRUE(hit.hit);
  EXPECT_NEAR(hit.range, 4.5, 1e-6);
}

TEST_F(OccupancyMapTest, TextPgmAndNegateAreRead) {
  write("map.pgm", "P2\n# comment\n3 2\n255\n0 255 128\n255 255 0\n");
  LoadMapResult r = load_map(yaml("map.pgm"));
  ASSERT_TRUE(r.ok()) << r.error_text();
  // Image row 0 (top) is iy = 1.
  EXPECT_EQ(r.map->cell_state(0, 1), CellState::kOccupied);
  EXPECT_EQ(r.map->cell_state(1, 1), CellState::kFree);
  EXPECT_EQ(r.map->cell_state(2, 1), CellState::kUnknown);
  EXPECT_EQ(r.map->cell_state(2, 0), CellState::kOccupied);
  write("map2.yaml",
        "image: map.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n");
  r = load_map((dir_ / "map2.yaml").string());
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_EQ(r.map->cell_state(0, 1), CellState::kFree);
  EXPECT_EQ(r.map->cell_state(1, 1), CellState::kOccupied);
}

TEST_F(OccupancyMapTest, MissingFilesAreNamed) {
  expect_error(load_map((dir_ / "nope.yaml").string()), {"nope.yaml", "cannot open the map file"});
  expect_error(load_map(yaml("absent.pgm")), {"absent.pgm", "cannot open the map image"});
}

TEST_F(OccupancyMapTest, YamlErrorsNameTheLineAndKey) {
  write("map.pgm", "P2\n1 1\n255\n0\n");
  expect_error(load_map(yaml("map.pgm", "colour: red\n")), {"map.yaml:7:", "unknown key 'colour'"});
  expect_error(load_map(write("a.yaml",
                              "image: map.pgm\nresolution: -1\norigin: [0, 0, 0]\nnegate: 0\n"
                              "occupied_thresh: 0.65\nfree_thresh: 0.196\n")),
               {"a.yaml:2:", "'resolution' must be positive"});
  expect_error(load_map(write("b.yaml",
                              "image: map.pgm\nresolution: 0.1\norigin: [0, 0]\nnegate: 0\n"
                              "occupied_thresh: 0.65\nfree_thresh: 0.196\n")),
               {"b.yaml:3:", "'origin' must be [x, y, yaw]"});
  expect_error(load_map(write("c.yaml",
                              "image: map.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\n"
                              "occupied_thresh: 0.1\nfree_thresh: 0.5\n")),
               {"c.yaml:6:", "'free_thresh' is above 'occupied_thresh'"});
  expect_error(load_map(write("d.yaml", "image: map.pgm\nresolution: 0.1\n")), {"d.yaml", "missing key 'origin'"});
  expect_error(load_map(write("e.yaml", "image: map.pgm\nresolution: [1\n")), {"e.yaml:", "YAML syntax"});
  expect_error(load_map(write("f.yaml",
                              "image: map.pgm\nresolution: abc\norigin: [0, 0, 0]\nnegate: 2\n"
                              "occupied_thresh: 0.65\nfree_thresh: 0.196\n")),
               {"f.yaml:2:", "'resolution' must be a finite number", "f.yaml:4:", "'negate' must be 0 or 1"});
}

TEST_F(OccupancyMapTest, ImageErrorsNameTheByteOffset) {
  write("png.pgm", "\x89PNG....");
  expect_error(load_map(yaml("png.pgm")), {"png.pgm: byte 0:", "not a PGM image"});
  // 4x4 raster promised, 6 bytes given: truncated, with the offsets.
  write("short.pgm", std::string("P5\n4 4\n255\n") + std::string(6, '\xff'));
  expect_error(load_map(yaml("short.pgm")), {"short.pgm: byte 17:", "truncated", "16 bytes from byte 11"});
  write("deep.pgm", "P5\n2 2\n65535\n");
  expect_error(load_map(yaml("deep.pgm")), {"deep.pgm: byte", "maxval 65535 is not supported"});
  write("head.pgm", "P5\n4\n");
  expect_error(load_map(yaml("head.pgm")), {"head.pgm: byte 5:", "file ends where the height should be"});
  write("text.pgm", "P2\n2 1\n255\n0 x\n");
  expect_error(load_map(yaml("text.pgm")), {"text.pgm: byte 13:", "expected the pixel value"});
  write("empty.pgm", "P5\n0 4\n255\n");
  expect_error(load_map(yaml("empty.pgm")), {"empty.pgm", "the image is empty"});
}

// Issue 17: a 22-byte PGM whose header claims 30000 x 30000 allocated 900 MB before
// the truncation was seen; /dev/zero as image grew the process to gigabytes; a FIFO
// hung loading. Each is now refused before anything is allocated, naming file and byte.
TEST_F(OccupancyMapTest, HostileImagesAreRefusedBeforeAllocation) {
  write("huge.pgm", "P5\n30000 30000\n255\n\xff\xff");  // 22 bytes
  expect_error(load_map(yaml("huge.pgm")),
               {"huge.pgm: byte 18:", "30000x30000 = 900000000 pixels, more than the limit of 67108864 map cells"});
  write("liar.pgm", "P5\n8000 8000\n255\n\xff\xff");  // within the cell limit, 64 MB promised, 2 bytes given
  expect_error(load_map(yaml("liar.pgm")), {"liar.pgm: byte", "truncated: the raster needs 64000000 bytes"});
  write("text.pgm", "P2\n8000 8000\n255\n0 0 0\n");
  expect_error(load_map(yaml("text.pgm")), {"text.pgm: byte 23:", "file ends where the pixel value should be"});
  write("side.pgm", "P5\n99999999999 1\n255\n");
  expect_error(load_map(yaml("side.pgm")), {"side.pgm: byte 3:", "width is larger than 100000"});
  test::HostileDir d("map");
  const std::string fifo = d.fifo("fifo.pgm");
  test::HangGuard guard("load_map with a FIFO as image");
  expect_error(load_map(yaml("/dev/zero")), {"/dev/zero: the map image is a character device, not a regular file"});
  expect_error(load_map(yaml(fifo)), {fifo + ": the map image is a FIFO, not a regular file"});
  expect_error(load_map(yaml(d.subdir("folder"))), {"folder: the map image is a directory"});
  const std::string big = d.sparse("big.pgm", kMaxMapImageBytes + 1);
  expect_error(load_map(yaml(big)), {"big.pgm: the map image has 256.0 MiB, more than the limit of 256 MiB"});
}

TEST_F(OccupancyMapTest, HostileYamlFilesAreRefused) {
  test::HostileDir d("map");
  const std::string fifo = d.fifo("fifo.yaml");
  test::HangGuard guard("load_map on a FIFO");
  expect_error(load_map(fifo), {fifo + ": the map file is a FIFO, not a regular file"});
  expect_error(load_map("/dev/zero"), {"/dev/zero: the map file is a character device"});
  expect_error(load_map(d.sparse("big.yaml", kMaxMapYamlBytes + 1)), {"big.yaml: the map file has", "limit of 1 MiB"});
  write("map.pgm", "P2\n1 1\n255\n0\n");
  expect_error(load_map(yaml("map.pgm", "resolution: 0.2\n")), {"map.yaml:7:", "key 'resolution' appears twice"});
  expect_error(load_map(write("g.yaml", std::string(50000, '[') + "\n")), {"g.yaml"});
  expect_error(load_map(write("n.yaml",
                              "image: {a: b}\nresolution: [1]\norigin: [[1], 2, 3]\nnegate: [0]\n"
                              "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: [x]\n")),
               {"n.yaml:1: 'image' must name the PGM file", "n.yaml:2: 'resolution' must be a finite number",
                "n.yaml:3: 'origin' entries must be finite numbers", "n.yaml:4: 'negate' must be 0 or 1",
                "n.yaml:7: 'mode' must be trinary"});
}

}  // namespace
}  // namespace rack::maps
