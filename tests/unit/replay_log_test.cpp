// Recorded logs: the CARMEN parser (each line kind, malformed lines with their number
// and reason) and the MRPT rawlog reader (a dataset Debian's mrpt-common ships, and
// files that are not rawlogs).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>
#include <variant>

#include <array>
#include <map>
#include <sstream>
#include <vector>

#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"
#include "rack/replay/carmen_log.h"
#include "rack/replay/replay_log.h"
#include "hostile_files.h"
#include "rawlog_reader.h"
#include "rack/rt/input_file.h"

#include <zlib.h>

namespace rack::replay {
namespace {

std::string reason_of(const CarmenLine& l) {
  const auto* m = std::get_if<CarmenMalformed>(&l);
  return m == nullptr ? std::string("(not malformed)") : m->reason;
}

TEST(CarmenLogTest, OdomLine) {
  const CarmenLine l = parse_carmen_line("ODOM 1.5 -2.25 0.5 0.3 -0.1 0.0 1234.5678 host 0.01", 7);
  const auto* o = std::get_if<OdometryRecord>(&l);
  ASSERT_NE(o, nullptr) << reason_of(l);
  EXPECT_DOUBLE_EQ(o->x, 1.5);
  EXPECT_DOUBLE_EQ(o->y, -2.25);
  EXPECT_DOUBLE_EQ(o->phi, 0.5);
  EXPECT_DOUBLE_EQ(o->tv, 0.3);
  EXPECT_DOUBLE_EQ(o->rv, -0.1);
  EXPECT_DOUBLE_EQ(o->time, 1234.5678);
  EXPECT_EQ(o->line, 7);
}

TEST(CarmenLogTest, FlaserLine) {
  const CarmenLine l = parse_carmen_line("FLASER 5 1.0 2.0 3.0 4.0 5.0 10.0 20.0 0.1 1.0 2.0 0.2 100.25 robot 0.5", 3);
  const auto* s = std::get_if<ScanRecord>(&l);
  ASSERT_NE(s, nullptr) << reason_of(l);
  ASSERT_EQ(s->ranges.size(), 5U);
  EXPECT_FLOAT_EQ(s->ranges[4], 5.0F);
  EXPECT_FLOAT_EQ(s->start_angle, static_cast<float>(-std::numbers::pi / 2));
  EXPECT_FLOAT_EQ(s->angle_step, static_cast<float>(std::numbers::pi / 4));  // 180 deg over 4 gaps
  EXPECT_TRUE(s->has_odometry);
  EXPECT_DOUBLE_EQ(s->odom_x, 1.0);  // odom_x, not the corrected x
  EXPECT_DOUBLE_EQ(s->odom_y, 2.0);
  EXPECT_DOUBLE_EQ(s->odom_phi, 0.2);
  EXPECT_DOUBLE_EQ(s->time, 100.25);
  EXPECT_GT(s->max_range, 0.0F);
}

TEST(CarmenLogTest, RobotLaser1Line) {
  // 3 beams from -0.5 rad by 0.5 rad, 3 remissions; laser 0.2 m ahead of the robot,
  // which stands at (1, 1) facing +y.
  const CarmenLine l = parse_carmen_line(
      "ROBOTLASER1 0 -0.5 1.0 0.5 30.0 0.01 0 3 1.5 2.5 3.5 3 10 20 30 "
      "1.0 1.2 1.5707963 1.0 1.0 1.5707963 0.4 0.1 0.5 0.3 0.0 55.5 host 1.0",
      9);
  const auto* s = std::get_if<ScanRecord>(&l);
  ASSERT_NE(s, nullptr) << reason_of(l);
  ASSERT_EQ(s->ranges.size(), 3U);
  ASSERT_EQ(s->intensities.size(), 3U);
  EXPECT_FLOAT_EQ(s->start_angle, -0.5F);
  EXPECT_FLOAT_EQ(s->angle_step, 0.5F);
  EXPECT_FLOAT_EQ(s->max_range, 30.0F);
  EXPECT_FLOAT_EQ(s->intensities[2], 30.0F);
  EXPECT_DOUBLE_EQ(s->odom_x, 1.0);
  EXPECT_DOUBLE_EQ(s->odom_phi, 1.5707963);
  EXPECT_NEAR(s->laser_x, 0.2, 1e-6);  // mounting, robot frame
  EXPECT_NEAR(s->laser_y, 0.0, 1e-6);
  EXPECT_NEAR(s->laser_phi, 0.0, 1e-6);
  EXPECT_DOUBLE_EQ(s->time, 55.5);
}

TEST(CarmenLogTest, CommentsBlankLinesAndOtherKindsAreIgnored) {
  EXPECT_TRUE(std::holds_alternative<CarmenIgnored>(parse_carmen_line("# a comment", 1)));
  EXPECT_TRUE(std::holds_alternative<CarmenIgnored>(parse_carmen_line("   \t", 1)));
  EXPECT_TRUE(std::holds_alternative<CarmenIgnored>(parse_carmen_line("PARAM robot_length 0.5 nohost 0", 1)));
  EXPECT_TRUE(std::holds_alternative<CarmenIgnored>(parse_carmen_line("TRUEPOS 1 2 3 4 5 6 7 h 8", 1)));
}

TEST(CarmenLogTest, MalformedLinesSayWhy) {
  struct Case {
    const char* line;
    const char* expect;
  };
  const Case cases[] = {
      {"ODOM 1 2 3 0.3 0.1 0 12.0 host", "missing logger_timestamp"},
      {"ODOM 1 2 x 0.3 0.1 0 12.0 host 0", "theta is not a number: 'x'"},
      {"ODOM 1 2 3 0.3 0.1 0 12.0 host 0 extra", "extra field"},
      {"ODOM 1 2 nan 0.3 0.1 0 12.0 host 0", "theta is not finite"},
      {"FLASER 5 1 2 3", "line ends inside the range readings"},
      {"FLASER 5 1 2 3 4.0 1 1 0 1 1 0 100 host 0", "ipc_timestamp is not a number: 'host'"},
      {"FLASER -3 1 2 3", "num_readings must be a count"},
      {"FLASER 2.5 1 2 3", "num_readings must be a count"},
      {"FLASER 1 5.0 1 1 0 1 1 0 100 host 0", "at least 2"},
      {"ROBOTLASER1 0 -0.5 1.0 0.5 30.0 0.01 0 3 1.5 2.5 3.5 2 10 20 1 1 0 1 1 0 0 0 0 0 0 5 h 1",
       "2 remission values for 3"},
      {"ROBOTLASER1 0 -0.5 1.0 0.5 0.0 0.01 0 2 1.5 2.5 0 1 1 0 1 1 0 0 0 0 0 0 5 h 1",
       "maximum_range must be positive"},
      {"\x01\x02garbage", "not a CARMEN message"},
  };
  for (const auto& c : cases) {
    const std::string why = reason_of(parse_carmen_line(c.line, 1));
    EXPECT_NE(why.find(c.expect), std::string::npos) << "line: " << c.line << "\nreason: " << why;
  }
}

TEST(CarmenLogTest, WholeLogKeepsRecordsSortedAndReportsLineNumbers) {
  const std::string text =
      "# CARMEN Logfile\n"
      "PARAM robot_width 0.5 nohost 0\n"
      "ODOM 0.1 0 0 0 0 0 2.0 h 2.0\n"
      "ODOM 0.0 0 0 0 0 0 1.0 h 1.0\n"
      "FLASER 3 1 2 3 0 0 0 0 0 0 1.5 h 1.5\n"
      "ODOM 1 2\n"
      "\n"
      "FLASER 3 1 2 three 0 0 0 0 0 0 1.7 h 1.7\n";
  const LoadLogResult r = parse_carmen_text(text, "test.log");
  EXPECT_EQ(r.lines, 8U);
  EXPECT_EQ(r.ignored, 1U);
  ASSERT_EQ(r.log.odometry.size(), 2U);
  EXPECT_DOUBLE_EQ(r.log.odometry[0].time, 1.0);  // sorted by time
  EXPECT_EQ(r.log.odometry[0].line, 4);
  ASSERT_EQ(r.log.scans.size(), 1U);
  ASSERT_EQ(r.errors.size(), 2U);
  EXPECT_EQ(r.errors[0].line, 6);
  EXPECT_EQ(r.errors[1].line, 8);
  EXPECT_NE(r.errors[1].str().find("test.log:8: FLASER: range reading is not a number: 'three'"), std::string::npos)
      << r.errors[1].str();
  EXPECT_DOUBLE_EQ(r.log.first_time(), 1.0);
  EXPECT_DOUBLE_EQ(r.log.last_time(), 2.0);
}

TEST(CarmenLogTest, MissingAndEmptyFilesAreErrors) {
  const LoadLogResult missing = load_replay_log("/nonexistent/robot.log");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error_text().find("/nonexistent/robot.log: cannot open"), std::string::npos);
  const LoadLogResult empty = parse_carmen_text("# nothing\n", "empty.log");
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error_text().find("no ODOM, FLASER or ROBOTLASER1"), std::string::npos);
}

// MRPT's own reader on a dataset Debian's mrpt-common ships (scripts/setup.sh installs
// it): an actions + sensory-frames rawlog with 2-D laser scans and odometry.
TEST(RawlogTest, ReadsMrptLocalisationDemo) {
  const std::string path = "/usr/share/mrpt/datasets/localization_demo.rawlog";
  ASSERT_TRUE(std::filesystem::exists(path)) << path << " missing: run scripts/setup.sh (mrpt-common)";
  const LoadLogResult r = load_replay_log(path);
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_GT(r.log.scans.size(), 10U);
  EXPECT_EQ(r.log.odometry.size(), r.log.scans.size());
  const ScanRecord& s = r.log.scans.front();
  EXPECT_GE(s.ranges.size(), 2U);
  EXPECT_GT(s.max_range, 0.0F);
  EXPECT_TRUE(s.has_odometry);
  // Odometry accumulates: the robot moves during the dataset.
  const auto& a = r.log.odometry.front();
  const auto& b = r.log.odometry.back();
  EXPECT_GT(std::hypot(b.x - a.x, b.y - a.y), 0.5);
  for (std::size_t i = 1; i < r.log.scans.size(); ++i) EXPECT_GE(r.log.scans[i].time, r.log.scans[i - 1].time);
}

TEST(RawlogTest, NotARawlogIsAnErrorWithTheFileName) {
  const auto path = std::filesystem::temp_directory_path() / "rack_bad_test.rawlog";
  {
    std::ofstream out(path, std::ios::binary);
    out << "this is not a rawlog, just text that MRPT cannot deserialise\n";
  }
  const LoadLogResult r = load_replay_log(path.string());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error_text().find(path.string()), std::string::npos) << r.error_text();
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace rack::replay

namespace rack::replay {
namespace {

// The example log shipped in configs/logs/ (written by bench_mcl --write-carmen), parsed
// and fed to MCL scan by scan: the estimate follows the TRUEPOS lines (ground truth,
// which the replay ignores; read here by hand).
TEST(CarmenLogTest, ShippedExampleLogLocalisesWithMcl) {
  const std::string dir = std::string(RACK_SOURCE_DIR) + "/configs";
  const LoadLogResult r = load_carmen_log(dir + "/logs/office_tour.clf");
  ASSERT_TRUE(r.ok()) << r.error_text();
  ASSERT_GT(r.log.scans.size(), 100U);
  std::map<double, std::array<double, 3>> truth;
  {
    std::ifstream in(dir + "/logs/office_tour.clf");
    std::string kind;
    for (std::string line; std::getline(in, line);) {
      std::istringstream ls(line);
      ls >> kind;
      if (kind != "TRUEPOS") continue;
      double x, y, th, ox, oy, oth, t;
      ls >> x >> y >> th >> ox >> oy >> oth >> t;
      truth[t] = {x, y, th};
    }
  }
  auto map = maps::load_map(dir + "/maps/office.yaml");
  ASSERT_TRUE(map.ok()) << map.error_text();
  mcl::MclOptions o;
  o.seed = 3;
  mcl::MclFilter f(*map.map, o);
  f.init_pose({2.0, 8.0, 0.0}, 0.2, 0.1);
  double sum_sq = 0;
  int n = 0;
  for (const ScanRecord& s : r.log.scans) {
    std::vector<float> xs, ys;
    for (std::size_t i = 0; i < s.ranges.size(); ++i) {
      if (!(s.ranges[i] > 0 && s.ranges[i] < s.max_range)) continue;
      const double a = s.start_angle + static_cast<double>(i) * s.angle_step;
      xs.push_back(static_cast<float>(s.ranges[i] * std::cos(a)));
      ys.push_back(static_cast<float>(s.ranges[i] * std::sin(a)));
    }
    if (!f.update({s.odom_x, s.odom_y, s.odom_phi}, xs, ys)) continue;
    const auto it = truth.find(s.time);
    ASSERT_NE(it, truth.end()) << "no TRUEPOS at " << s.time;
    const auto e = f.estimate();
    const double err = std::hypot(e.pose.x - it->second[0], e.pose.y - it->second[1]);
    if (++n > 5) sum_sq += err * err;
  }
  ASSERT_GT(n, 50);
  EXPECT_LT(std::sqrt(sum_sq / (n - 5)), 0.05);
}

}  // namespace
}  // namespace rack::replay

namespace rack::replay {
namespace {

// A rawlog cut in the middle of a record is an error naming the byte offset, not a
// shorter log.
TEST(RawlogTest, TruncatedRawlogIsAnErrorWithTheOffset) {
  const std::string src = "/usr/share/mrpt/datasets/localization_demo.rawlog";
  ASSERT_TRUE(std::filesystem::exists(src)) << src << " missing: run scripts/setup.sh (mrpt-common)";
  const auto path = std::filesystem::temp_directory_path() / "rack_truncated_test.rawlog";
  {
    std::ifstream in(src, std::ios::binary);
    std::ostringstream whole;
    whole << in.rdbuf();
    std::string bytes = whole.str();
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  }
  const LoadLogResult r = load_replay_log(path.string());
  ASSERT_FALSE(r.ok()) << "a truncated rawlog was accepted with " << r.log.scans.size() << " scans";
  EXPECT_NE(r.error_text().find("byte offset"), std::string::npos) << r.error_text();
  EXPECT_NE(r.error_text().find(path.string()), std::string::npos) << r.error_text();
  std::filesystem::remove(path);
}

// Issue 17: log files from hostile places are refused without waiting or reading for
// ever, each error naming the file.
TEST(HostileLogTest, FifosDevicesDirectoriesAndHugeFilesAreRefused) {
  test::HostileDir d("log");
  const std::string fifo_log = d.fifo("fifo.log");
  const std::string fifo_rawlog = d.fifo("fifo.rawlog");
  const std::string huge = d.sparse("huge.log", kMaxLogFileBytes + 1);
  test::HangGuard guard("load_replay_log on a FIFO");
  const std::pair<std::string, std::string> cases[] = {
      {fifo_log, fifo_log + ": the log file is a FIFO, not a regular file"},
      {fifo_rawlog, fifo_rawlog + ": the rawlog is a FIFO, not a regular file"},
      {"/dev/zero", "/dev/zero: the log file is a character device, not a regular file"},
      {d.subdir("dir.rawlog"), "dir.rawlog: the rawlog is a directory"},
      {huge, huge + ": the log file has 256.0 MiB, more than the limit of 256 MiB"},
  };
  for (const auto& [path, expect] : cases) {
    const LoadLogResult r = load_replay_log(path);
    EXPECT_FALSE(r.ok()) << path;
    EXPECT_NE(r.error_text().find(expect), std::string::npos) << r.error_text();
  }
}

TEST(HostileLogTest, AFloodOfBadLinesKeepsTheFirstErrorsAndCountsAll) {
  std::string text;
  for (int i = 0; i < 5000; ++i) text += "ODOM x\n";
  const LoadLogResult r = parse_carmen_text(text, "flood.log");
  EXPECT_EQ(r.errors.size(), kMaxLogErrors);
  EXPECT_EQ(r.error_count, 5000u);
  EXPECT_EQ(r.errors.front().str().rfind("flood.log:1: ODOM: x is not a number", 0), 0u) << r.errors.front().str();
  EXPECT_NE(r.error_text(10).find("(4990 more)"), std::string::npos) << r.error_text(10);
}

TEST(HostileLogTest, HugeBeamCountsAreRefusedBeforeAllocation) {
  const CarmenLine l = parse_carmen_line("FLASER 4294967296 1 2 3", 1);
  const auto* e = std::get_if<CarmenMalformed>(&l);
  ASSERT_NE(e, nullptr);
  EXPECT_NE(e->reason.find("num_readings must be a count 0..100000"), std::string::npos) << e->reason;
  const CarmenLine m = parse_carmen_line("FLASER 100000 1 2 3", 1);
  const auto* f = std::get_if<CarmenMalformed>(&m);
  ASSERT_NE(f, nullptr);
  EXPECT_NE(f->reason.find("line ends inside the range readings: 3 fields left, 100000 needed"), std::string::npos)
      << f->reason;
}

TEST(HostileLogTest, GzipBombsGarbageAndTruncatedGzipAreRefused) {
  // 64 MiB of zeros compress to about 64 KiB: inflating stops at the limit.
  std::string zeros(64u << 20, '\0');
  std::string gz;
  {
    z_stream z{};
    ASSERT_EQ(deflateInit2(&z, 9, Z_DEFLATED, 16 + MAX_WBITS, 9, Z_DEFAULT_STRATEGY), Z_OK);
    gz.resize(deflateBound(&z, zeros.size()));
    z.next_in = reinterpret_cast<Bytef*>(zeros.data());
    z.avail_in = static_cast<uInt>(zeros.size());
    z.next_out = reinterpret_cast<Bytef*>(gz.data());
    z.avail_out = static_cast<uInt>(gz.size());
    ASSERT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
    gz.resize(z.total_out);
    deflateEnd(&z);
  }
  zeros.clear();
  zeros.shrink_to_fit();
  std::string out, error;
  EXPECT_FALSE(gunzip_bounded(gz, 1u << 20, out, error));
  EXPECT_NE(error.find("decompresses to more than the limit of 1048576 bytes"), std::string::npos) << error;
  EXPECT_TRUE(out.empty());
  EXPECT_FALSE(gunzip_bounded(gz.substr(0, gz.size() / 2), 128u << 20, out, error));
  EXPECT_NE(error.find("gzip data is truncated"), std::string::npos) << error;
  std::string corrupt = gz;
  corrupt[12] = static_cast<char>(corrupt[12] ^ 0x55);
  corrupt[13] = static_cast<char>(corrupt[13] ^ 0x55);
  EXPECT_FALSE(gunzip_bounded(corrupt, 128u << 20, out, error));
  EXPECT_NE(error.find("byte offset"), std::string::npos) << error;
  // Garbage that MRPT cannot deserialise: an error naming the record and offset.
  const LoadLogResult g = parse_rawlog("garbage.rawlog", std::string(4096, '\x7f'));
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error_text().find("garbage.rawlog: record 0 at byte offset 0"), std::string::npos) << g.error_text();
  // A cut record of a real rawlog (uncompressed, as MRPT reads it): the offset is named.
  std::string plain, why;
  {
    std::string gz_file;
    ASSERT_TRUE(
        rt::read_regular_file("/usr/share/mrpt/datasets/localization_demo.rawlog", 1u << 20, "rawlog", gz_file, why))
        << why << " (mrpt-common missing? run scripts/setup.sh)";
    ASSERT_TRUE(gunzip_bounded(gz_file, 1u << 20, plain, why)) << why;
  }
  const LoadLogResult cut = parse_rawlog("cut.rawlog", plain.substr(0, 3000));
  EXPECT_FALSE(cut.ok());
  EXPECT_NE(cut.error_text().find("cut.rawlog: record "), std::string::npos) << cut.error_text();
  EXPECT_NE(cut.error_text().find("truncated at byte offset"), std::string::npos) << cut.error_text();
}

// Found by fuzz_rawlog: a corrupt JPEG in a CImage (here under its old name
// CMRPTImage) made libjpeg call exit() inside MRPT's deserialisation: rackd ended.
TEST(HostileLogTest, ImagesAreNotHandedToMrptsJpegDecoder) {
  const std::string bytes(
      "\x8a"
      "CMRPTImage\x03serN4mrpt21Excei:",
      29);
  const LoadLogResult r = parse_rawlog("image.rawlog", bytes);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error_text().find("image.rawlog: record 0 at byte offset 0 (uncompressed) holds an image"),
            std::string::npos)
      << r.error_text();
}

// Found by fuzz_rawlog: 150 bytes made MRPT dereference a null pointer inside
// CActionRobotMovement2D::serializeFrom. load_rawlog() runs MRPT in a child process:
// the crash is an error naming the record, and this process lives on.
TEST(HostileLogTest, AnMrptCrashIsAnErrorOfTheRecordNotOfTheProcess) {
  const std::string seed = std::string(RACK_SOURCE_DIR) + "/tests/unit/data/rawlog_mrpt_segv_movement2d.rawlog";
  const LoadLogResult r = load_replay_log(seed);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error_text().find(seed + ": record 0 at byte offset 0 (uncompressed): MRPT's reader crashed on it"),
            std::string::npos)
      << r.error_text();
  // Found by fuzz_rawlog (an OOM): a record claiming a string of gigabytes. MRPT takes
  // the memory before it finds the data missing; in the child that is bounded by its
  // address-space limit, and here an error.
  const std::string claim = std::string(RACK_SOURCE_DIR) + "/tests/unit/data/rawlog_huge_claim.rawlog";
  const LoadLogResult c = load_replay_log(claim);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error_text().find(claim + ": record "), std::string::npos) << c.error_text();
  // The corrupt JPEG whose decoder calls exit(): in the child, images are read, and the
  // exit ends only the child.
  const std::string jpeg = std::string(RACK_SOURCE_DIR) +
                           "/tests/fuzz/corpus/rawlog/regression_corrupt_jpeg_exit.rawlog";
  const LoadLogResult j = load_replay_log(jpeg);
  ASSERT_FALSE(j.ok());
  EXPECT_NE(j.error_text().find(jpeg + ": record 0 at byte offset 0 (uncompressed)"), std::string::npos)
      << j.error_text();
  // The isolated reader returns what a good rawlog holds, as the in-process one does.
  const std::string demo = "/usr/share/mrpt/datasets/localization_demo.rawlog";
  std::string bytes, why;
  ASSERT_TRUE(rt::read_regular_file(demo, 1u << 20, "rawlog", bytes, why)) << why;
  const LoadLogResult isolated = load_replay_log(demo);
  const LoadLogResult direct = parse_rawlog(demo, bytes);
  ASSERT_TRUE(isolated.ok()) << isolated.error_text();
  ASSERT_EQ(isolated.log.scans.size(), direct.log.scans.size());
  ASSERT_EQ(isolated.log.odometry.size(), direct.log.odometry.size());
  EXPECT_EQ(isolated.lines, direct.lines);
  for (std::size_t i = 0; i < direct.log.scans.size(); ++i) {
    EXPECT_EQ(isolated.log.scans[i].ranges, direct.log.scans[i].ranges);
    EXPECT_EQ(isolated.log.scans[i].time, direct.log.scans[i].time);
  }
  for (std::size_t i = 0; i < direct.log.odometry.size(); ++i)
    EXPECT_EQ(isolated.log.odometry[i].x, direct.log.odometry[i].x);
}

}  // namespace
}  // namespace rack::replay
