// End to end: rack-foxglove (tools/foxglove, node) over rack-gui and a real rackd
// running the simulated robot of configs/sim_mcl.yaml on a private LCM bus, checked by
// tools no one here wrote:
//   - Foxglove's WebSocket client (@foxglove/ws-protocol) receives typed messages on
//     the expected channels, calls a service and reads and sets parameters
//     (tools/foxglove/test/live_check.mjs);
//   - the recorder's MCAP file is read record by record and through its index by the
//     npm MCAP reader (@mcap/core; tools/foxglove/test/mcap_check.mjs), with zstd and
//     lz4 chunks, and holds every sample of the streams it recorded;
//   - a recording played back into MCL gives the recorded localisation;
//   - every recorded class plays back sample for sample (time to the ns, every field);
//   - the player refuses a malformed MCAP file saying what and where;
//   - rack-foxglove installed by `cmake --install` runs from the installed tree.
//
// Skips (with the reason) only when node is not installed; a missing `npm ci` in
// tools/foxglove is a failure (scripts/setup.sh does it).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kGui = RACK_GUI_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;
const std::string kFoxglove = RACK_FOXGLOVE_DIR;
const std::string kCmake = RACK_CMAKE;
const std::string kBinaryDir = RACK_BINARY_DIR;

// The text after `prefix` up to the next space in `text` ("" when absent).
std::string word_after(const std::string& text, const std::string& prefix) {
  const auto at = text.find(prefix);
  if (at == std::string::npos) return "";
  const auto from = at + prefix.size();
  return text.substr(from, text.find_first_of(" \n", from) - from);
}

// The integer just before `suffix` in `text` (-1 when absent): "3 not answered" -> 3.
long count_before(const std::string& text, const std::string& suffix) {
  const auto at = text.find(suffix);
  if (at == std::string::npos || at == 0) return -1;
  auto from = at;
  while (from > 0 && std::isdigit(static_cast<unsigned char>(text[from - 1])) != 0) --from;
  return from == at ? -1 : std::stol(text.substr(from, at - from));
}

class FoxgloveTest : public ::testing::Test {
 protected:
  FoxgloveTest() : watchdog_(110s, "FoxgloveTest") {}

  void SetUp() override {
    node_ = find_program("node");
    if (!node_) GTEST_SKIP() << "node is not installed (Debian: apt-get install nodejs); scripts/setup.sh installs it";
    ASSERT_TRUE(std::filesystem::exists(kFoxglove + "/node_modules/@foxglove/ws-protocol"))
        << "tools/foxglove's packages are missing: run scripts/setup.sh (npm ci in " << kFoxglove << ")";
  }

  // A file of configs/ with absolute map paths (rackd then needs no working directory).
  std::string config(const std::string& name) {
    std::string text = read_file(kConfigs + "/" + name);
    const std::string rel = "map: maps/office.yaml";
    const std::string abs = "map: " + kConfigs + "/maps/office.yaml";
    for (auto at = text.find(rel); at != std::string::npos; at = text.find(rel, at + abs.size()))
      text.replace(at, rel.size(), abs);
    return dir_.write(name, text).string();
  }

  // rackd on a host file of configs/.
  void start_robot(const std::string& host_file) {
    rackd_.emplace(std::vector<std::string>{kRackd, config(host_file), "--lcm", bus_.url()}, dir_.path(), "rackd");
    EXPECT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  }

  // rack-gui on the test's bus (`lcm_options` appended to its LCM URL); returns its
  // WebSocket URL.
  std::string start_gui(const std::string& lcm_options = "") {
    // (rack-gui serves a front end; the bridge needs none: a placeholder page.)
    std::filesystem::create_directories(dir_.path() / "web");
    const auto web = dir_.write("web/index.html", "<!doctype html><title>rack-gui</title>\n").parent_path();
    gui_.emplace(std::vector<std::string>{kGui, "--port", "0", "--lcm", bus_.url() + lcm_options, "--web", web.string(),
                                          "--reports", ""},
                 dir_.path(), "rack-gui");
    EXPECT_TRUE(gui_->wait_for_stderr("rack-gui: serving http://", 15s)) << gui_->err();
    const std::string http = word_after(gui_->err(), "rack-gui: serving ");
    EXPECT_EQ(http.rfind("http://", 0), 0u) << gui_->err();
    std::string ws = "ws://" + http.substr(7);
    if (!ws.empty() && ws.back() == '/') ws.pop_back();
    return ws + "/ws";
  }

  // rackd on a host file of configs/ (default: the simulated robot), and rack-gui on it;
  // returns rack-gui's WebSocket URL.
  std::string start_robot_and_gui(const std::string& host_file = "sim_mcl.yaml") {
    start_robot(host_file);
    return start_gui();
  }

  // What rack-gui and rackd said, for a failure's message.
  std::string logs() const {
    std::string out;
    if (gui_) out += "\nrack-gui:\n" + gui_->err();
    if (rackd_) out += "\nrackd:\n" + rackd_->err();
    return out;
  }

  // sim_mcl's laser scans and odometry, recorded for `seconds` into `file` (every
  // sample: lz4 chunks); rackd and rack-gui stopped after.
  void record_scans_and_odometry(const std::string& file, const char* seconds) {
    const std::string gui_ws = start_robot_and_gui();
    const RunResult rec = run({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--no-server", "--record",
                               file, "--topics", "^/rack/0/(ladar|odometry|mcl|chassis)$", "--compression", "lz4",
                               "--duration", seconds},
                              30s);
    ASSERT_EQ(rec.exit_code, 0) << rec.describe() << logs();
    stop_robot_and_gui();
  }

  void replay_into_mcl(const std::string& host_file, const std::string& played_topics);

  void stop_robot_and_gui() {
    for (auto* p : {&gui_, &rackd_}) {
      if (!*p) continue;
      (*p)->signal(SIGTERM);
      EXPECT_TRUE((*p)->wait_exit(15s).has_value()) << (*p)->err();
      p->reset();
    }
  }

  std::optional<std::string> node_;
  TempDir dir_;
  LcmBus bus_;
  Watchdog watchdog_;
  std::optional<Process> rackd_;
  std::optional<Process> gui_;
};

TEST_F(FoxgloveTest, FoxgloveClientReceivesTypedChannelsCallsServicesAndSetsParameters) {
  const std::string gui_ws = start_robot_and_gui();
  Process bridge({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--port", "0"}, dir_.path(),
                 "rack-foxglove");
  ASSERT_TRUE(bridge.wait_for_stderr("(Foxglove WebSocket)", 15s)) << bridge.err();
  const std::string url = word_after(bridge.err(), "rack-foxglove: serving ");
  ASSERT_EQ(url.rfind("ws://127.0.0.1:", 0), 0u) << bridge.err();

  const RunResult r = run({*node_, kFoxglove + "/test/live_check.mjs", "--url", url, "--timeout", "40"}, 60s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe() << "\nrack-foxglove:\n" << bridge.err();
  EXPECT_NE(r.out.find("all checks passed"), std::string::npos) << r.out;

  // The bridge outlives its clients and stops cleanly on SIGTERM, with the hostile
  // client's malformed messages (not JSON, a truncated and an unknown binary one) counted.
  ASSERT_TRUE(bridge.running()) << bridge.err();
  bridge.signal(SIGTERM);
  EXPECT_EQ(bridge.wait_exit(10s), std::optional<int>(0)) << bridge.err();
  const std::string err = bridge.err();
  const auto at = err.find(" malformed Foxglove client message(s) refused");
  ASSERT_NE(at, std::string::npos) << err;
  const auto start = err.rfind(' ', at - 1) + 1;
  EXPECT_GE(std::stoi(err.substr(start, at - start)), 3) << err;
}

TEST_F(FoxgloveTest, RecorderWritesMcapThatTheMcapReaderChecksRecordByRecord) {
  const std::string gui_ws = start_robot_and_gui();
  const std::string file = (dir_.path() / "sim.mcap").string();
  Process rec({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--no-server", "--record", file, "--duration",
               "6"},
              dir_.path(), "rack-foxglove");
  ASSERT_TRUE(rec.wait_for_stderr("rack-foxglove: recording", 15s)) << rec.err();
  // A parameter change: its GDOS line is recorded on /rack/gdos.
  std::this_thread::sleep_for(1500ms);
  const RunResult set = run(
      {kRackctl, "--lcm", bus_.url(), "--discover-ms", "2000", "set-param", "pilot", "vx_max", "0.5"}, 20s);
  EXPECT_EQ(set.exit_code, 0) << set.describe();
  ASSERT_EQ(rec.wait_exit(20s), std::optional<int>(0)) << rec.err();
  EXPECT_NE(rec.err().find("rack-foxglove: wrote "), std::string::npos) << rec.err();
  EXPECT_NE(rec.err().find(" 0 stream sample(s) lost on the way, 0 dropped by the recorder"), std::string::npos)
      << rec.err();

  const RunResult r = run(
      {*node_, kFoxglove + "/test/mcap_check.mjs", file, "--compression", "zstd", "--min-messages", "50", "--topic",
       "/rack/0/map", "--topic", "/rack/0/ladar/scan", "--topic", "/rack/0/scan2d/points", "--topic",
       "/rack/0/mcl/pose", "--topic", "/rack/0/mcl/particles", "--topic", "/rack/0/chassis", "--topic", "/rack/gdos",
       // Every sample (sequence numbers without a gap, count = rate x
       // time within two samples, the recorder's own count: none
       // lost): the chassis at 100 Hz, the ladar and scan2d at 25 Hz.
       "--every-sample", "/rack/0/chassis=100", "--every-sample", "/rack/0/ladar=25", "--every-sample",
       "/rack/0/scan2d=25",
       // Logged at the producers' times: each scan at the ladar's scan
       // time, and each scan MCL used (its data's scan_time_ns) is a
       // recorded scan at that time, to the ns.
       "--same-times", "/rack/0/scan2d=/rack/0/ladar", "--scan-times", "/rack/0/mcl=/rack/0/scan2d"},
      30s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_NE(r.out.find("all checks passed"), std::string::npos) << r.out;

  // Cut short after its first chunk (a recorder killed before its summary), the file
  // still gives the player that chunk's messages.
  const RunResult cut = run({*node_, kFoxglove + "/test/truncated_check.mjs", file}, 30s);
  std::printf("%s", cut.out.c_str());
  EXPECT_EQ(cut.exit_code, 0) << cut.describe();
}

// Replay (issue 24): sim_mcl's laser scans, chassis and odometry recorded as MCAP at
// their full rate (lz4 chunks; the npm MCAP reader checks first that every sample is
// there), played back with `rack-foxglove play` into a host of playback classes and
// live components, and MCL, initialised at the recorded pose, gives the recorded
// localisation: every replayed estimate within 0.15 m and 0.05 rad of the recorded MCL
// pose at the same scan time. `host_file` and `played` (the channels played) say which.
void FoxgloveTest::replay_into_mcl(const std::string& host_file, const std::string& played_topics) {
  const std::string recorded = (dir_.path() / "sim.mcap").string();
  ASSERT_NO_FATAL_FAILURE(record_scans_and_odometry(recorded, "8"));
  const RunResult check = run({*node_, kFoxglove + "/test/mcap_check.mjs", recorded, "--compression", "lz4",
                               "--min-messages", "100", "--every-sample", "/rack/0/ladar=25", "--every-sample",
                               "/rack/0/odometry=100", "--every-sample", "/rack/0/chassis=100"},
                              30s);
  std::printf("%s", check.out.c_str());
  ASSERT_EQ(check.exit_code, 0) << check.describe();
  const std::string gui_ws = start_robot_and_gui(host_file);
  const std::string replayed = (dir_.path() / "replay.mcap").string();
  Process rec({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--no-server", "--record", replayed,
               "--topics", "^/rack/0/mcl$"},
              dir_.path(), "rack-foxglove-record");
  ASSERT_TRUE(rec.wait_for_stderr("rack-foxglove: recording", 15s)) << rec.err();
  const RunResult played = run({*node_, kFoxglove + "/rack-foxglove.mjs", "play", recorded, "--gui", gui_ws, "--topics",
                                played_topics, "--init-mcl", "mcl", "--speed", "2"},
                               60s);
  std::printf("%s", played.err.c_str());
  ASSERT_EQ(played.exit_code, 0) << played.describe() << "\nrack-foxglove (recording):\n" << rec.err() << logs();
  EXPECT_NE(played.err.find("0 refused or skipped"), std::string::npos) << played.err;
  std::this_thread::sleep_for(1s);  // the last estimates streamed
  rec.signal(SIGTERM);
  ASSERT_EQ(rec.wait_exit(15s), std::optional<int>(0)) << rec.err() << logs();

  const RunResult r = run({*node_, kFoxglove + "/test/replay_check.mjs", recorded, replayed, "--max-xy", "0.15",
                           "--max-phi", "0.05", "--min-compared", "10"},
                          30s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe() << logs();
}

// The recorded laser and odometry (configs/replay_mcap_mcl.yaml: LadarPlayback and
// OdometryPlayback; Scan2D builds the scans there with the played odometry at their
// times, and MCL runs its motion model on it).
TEST_F(FoxgloveTest, ReplayIntoMclGivesTheRecordedLocalisation) {
  replay_into_mcl("replay_mcap_mcl.yaml", "^/rack/0/(ladar|odometry)$");
}

// As the CARMEN replay drivers: the recorded chassis and laser
// (configs/replay_mcap_chassis_mcl.yaml: ChassisPlayback and LadarPlayback); Odometry
// integrates the played chassis' increments live, and Scan2D and MCL run on it.
TEST_F(FoxgloveTest, ChassisAndLaserReplayedIntoOdometryAndMclGiveTheRecordedLocalisation) {
  replay_into_mcl("replay_mcap_chassis_mcl.yaml", "^/rack/0/(chassis|ladar)$");
}

// The converter's list of components (tools/foxglove/test/convert_check.mjs): each
// "components" message replaces it, so a component listed under its class number
// (Class0x11(0/0)) before its description came is listed once, under its class name,
// after; a malformed list is skipped, never thrown.
TEST_F(FoxgloveTest, ConverterTakesEachComponentsMessageAsTheWholeList) {
  const RunResult r = run({*node_, kFoxglove + "/test/convert_check.mjs"}, 30s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_NE(r.out.find("all checks passed"), std::string::npos) << r.out;
}

// The player started before its host (rack-foxglove play waits --wait S for the
// components): rack-gui lists each component under its class number, Class0x11(0/0),
// in the first round it sees the host, and under its class name, Ladar(0/0), once the
// class description has come (GET_STATUS, then GET_CLASS). The player follows the
// rename and plays every sample into LadarPlayback and OdometryPlayback. It once kept
// the first entry and waited for a class that never came: under CI load, where the
// descriptions come late, ReplayIntoMclGivesTheRecordedLocalisation failed so.
TEST_F(FoxgloveTest, PlayerStartedBeforeItsHostFollowsTheComponentsOnceDescribed) {
  const std::string recorded = (dir_.path() / "sim.mcap").string();
  ASSERT_NO_FATAL_FAILURE(record_scans_and_odometry(recorded, "3"));
  const std::string gui_ws = start_gui();  // no host on the bus yet
  Process play({*node_, kFoxglove + "/rack-foxglove.mjs", "play", recorded, "--gui", gui_ws, "--topics",
                "^/rack/0/(ladar|odometry)$", "--speed", "0", "--wait", "30"},
               dir_.path(), "rack-foxglove-play");
  // Connected, and nothing listed: then the host starts.
  ASSERT_TRUE(play.wait_for_stderr("rack-foxglove: waiting up to 30 s", 15s)) << play.err() << logs();
  EXPECT_NE(play.err().find("/rack/0/ladar: no component of that name"), std::string::npos) << play.err();
  start_robot("replay_mcap_mcl.yaml");
  const auto code = play.wait_exit(60s);
  const std::string err = play.err();
  std::printf("%s", err.c_str());
  ASSERT_EQ(code, std::optional<int>(0)) << err << logs();
  EXPECT_NE(err.find("playing /rack/0/ladar into Ladar(0/0) (LadarPlayback)"), std::string::npos) << err;
  EXPECT_NE(err.find("playing /rack/0/odometry into Odometry(0/0) (OdometryPlayback)"), std::string::npos) << err;
  EXPECT_NE(err.find("; 0 refused or skipped"), std::string::npos) << err;
}

// Every class plays back (issue 24): sim_mcl's chassis, odometry, ladar, scan2d,
// position, path and MCL recorded at their full rate (the path made again while
// recorded: it is published when made), played with `rack-foxglove play --speed 0`
// into configs/replay_mcap_sim.yaml, where a playback class stands in for each
// (ChassisPlayback, OdometryPlayback, LadarPlayback, Scan2dPlayback, PositionPlayback,
// PathPlayback, MclPlayback), and that host recorded again: the npm MCAP reader finds
// the recorded samples of every channel in the replay, in order, at their recorded time
// to the nanosecond and with every field the same (tools/foxglove/test/
// roundtrip_check.mjs). TiMS runs over LCM (UDP): on a loaded machine a datagram is
// lost now and then, and each such sample is counted (by the player: not answered; by
// the replay's recorder: a gap in the sequence numbers). The check allows exactly those
// as missing, and at most 1 % of the samples; none refused.
TEST_F(FoxgloveTest, EveryRecordedClassPlaysBackSampleForSample) {
  const std::string topics = "^/rack/0/(chassis|odometry|ladar|scan2d|position|path|mcl)$";
  const std::vector<std::string> components = {"Chassis(0/0)",  "Odometry(0/0)", "Ladar(0/0)", "Scan2D(0/0)",
                                               "Position(0/0)", "Path(0/0)",     "MCL(0/0)"};
  // The recorder's line once rack-gui streams a component to it.
  const auto wait_streaming = [&](Process& rec) {
    for (const auto& c : components) {
      ASSERT_TRUE(rec.wait_for_stderr("stream of " + c + ": " + c + ": streaming", 20s)) << rec.err() << logs();
    }
  };
  const std::string recorded = (dir_.path() / "sim.mcap").string();
  {
    const std::string gui_ws = start_robot_and_gui();
    Process rec({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--no-server", "--record", recorded,
                 "--topics", topics, "--duration", "5"},
                dir_.path(), "rack-foxglove-record");
    ASSERT_NO_FATAL_FAILURE(wait_streaming(rec));
    const RunResult set = run({kRackctl, "--lcm", bus_.url(), "--discover-ms", "2000", "set-param", "path", "waypoints",
                               "4,7.2; 12,7.6; 20,7.2; 21.5,8; 20,8.8; 12,8.4; 4,8.8; 2.5,8.1"},
                              20s);
    EXPECT_EQ(set.exit_code, 0) << set.describe();
    ASSERT_EQ(rec.wait_exit(30s), std::optional<int>(0)) << rec.err() << logs();
    stop_robot_and_gui();
  }
  const std::string gui_ws = start_robot_and_gui("replay_mcap_sim.yaml");
  const std::string replayed = (dir_.path() / "replay.mcap").string();
  Process rec({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--no-server", "--record", replayed,
               "--topics", topics},
              dir_.path(), "rack-foxglove-record");
  ASSERT_NO_FATAL_FAILURE(wait_streaming(rec));
  const RunResult played = run({*node_, kFoxglove + "/rack-foxglove.mjs", "play", recorded, "--gui", gui_ws, "--topics",
                                topics, "--speed", "0"},
                               60s);
  std::printf("%s", played.err.c_str());
  const long samples = count_before(played.err, " samples in ");
  const long unanswered = count_before(played.err, " not answered");
  ASSERT_TRUE(played.exit_code == 0 || (played.exit_code == 1 && unanswered > 0))
      << played.describe() << "\nrack-foxglove (recording):\n"
      << rec.err() << logs();
  EXPECT_NE(played.err.find("; 0 refused or skipped"), std::string::npos) << played.err;
  std::this_thread::sleep_for(1s);  // the last samples on their way to the recorder
  rec.signal(SIGTERM);
  ASSERT_EQ(rec.wait_exit(15s), std::optional<int>(0)) << rec.err() << logs();
  const long lost = count_before(rec.err(), " stream sample(s) lost on the way");
  ASSERT_GE(lost, 0) << rec.err();
  ASSERT_GE(unanswered, 0) << played.err;
  EXPECT_LE(100 * (lost + unanswered), samples) << "more than 1 % lost on the way\n" << played.err << rec.err();

  std::vector<std::string> check{*node_,
                                 kFoxglove + "/test/roundtrip_check.mjs",
                                 recorded,
                                 replayed,
                                 "--allow-missing",
                                 std::to_string(lost + unanswered)};
  for (const char* t : {"chassis", "odometry", "ladar", "scan2d", "position", "path", "mcl"}) {
    check.insert(check.end(), {"--topic", std::string("/rack/0/") + t});
  }
  const RunResult r = run(check, 30s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe() << logs();
}

// The recorder on its own (tools/foxglove/test/recorder_check.mjs): each message
// logged at its sample's time to the nanosecond; samples lost on the way (gaps in a
// stream's sequence numbers) and dropped by a recorder that cannot keep up counted,
// said and kept in the file (Metadata "rack.recorder"). No robot needed.
TEST_F(FoxgloveTest, RecorderLogsSampleTimesToTheNanosecondAndCountsWhatItLoses) {
  const RunResult r = run({*node_, kFoxglove + "/test/recorder_check.mjs", dir_.path().string()}, 60s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_NE(r.out.find("all checks passed"), std::string::npos) << r.out;
}

// The player given malformed MCAP files (tools/foxglove/test/malformed_check.mjs):
// wrong magic, empty, cut in the header and in the first chunk, a corrupt chunk, an
// unknown compression, a huge chunk or record length, and channels of schemas it does
// not know: each refused before rack-gui is joined (exit 2), saying what and where
// (byte offset, record), without a stack trace, within the check's 30 s; then 300
// seeded random mutations through its reader, each read or refused, nothing thrown
// otherwise.
TEST_F(FoxgloveTest, PlayerRefusesMalformedRecordingsSayingWhatAndWhere) {
  const RunResult r = run({*node_, kFoxglove + "/test/malformed_check.mjs", dir_.path().string()}, 90s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_NE(r.out.find("all checks passed"), std::string::npos) << r.out;
}

// A camera (issue 24): rack-gui's images (polled once a second: a camera's samples are
// larger than a stream slot) as foxglove.RawImage on /rack/0/camera/image, seen by
// Foxglove's WebSocket client with the frames' pixels (tools/foxglove/test/
// image_check.mjs), and recorded: the npm MCAP reader finds them in the file.
TEST_F(FoxgloveTest, CameraImagesAreRawImagesLiveAndRecorded) {
  std::filesystem::create_directories(dir_.path() / "frames");
  for (int i = 0; i < 5; ++i) {
    std::string ppm = "P6\n64 48\n255\n";
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) {
        ppm += static_cast<char>(x * 4);
        ppm += static_cast<char>(y * 5);
        ppm += static_cast<char>(i * 50);
      }
    }
    char name[32];
    std::snprintf(name, sizeof name, "frames/img_%03d.ppm", i);
    (void)dir_.write(name, ppm);
  }
  const std::string host = dir_.write("camera.yaml",
                                      "host: camera-test\n"
                                      "system: 0\n"
                                      "lcm: true\n"
                                      "components:\n"
                                      "  - name: camera\n"
                                      "    class: Camera\n"
                                      "    instance: 0\n"
                                      "    autostart: true\n"
                                      "    data_task: {period_ms: 100, ring: 4}\n"
                                      "    params: {source: " +
                                          (dir_.path() / "frames/img_%03d.ppm").string() + ", loop: true, fps: 10}\n")
                               .string();
  rackd_.emplace(std::vector<std::string>{kRackd, host, "--lcm", bus_.url()}, dir_.path(), "rackd");
  ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  // A 0.9 MB image is ~16 datagrams at once: a receive buffer that holds them (as
  // GuiE2eTest's rack-gui; README: TiMS over LCM).
  const std::string gui_ws = start_gui("&recv_buf_size=4194304");
  const std::string file = (dir_.path() / "camera.mcap").string();
  Process bridge({*node_, kFoxglove + "/rack-foxglove.mjs", "--gui", gui_ws, "--port", "0", "--record", file},
                 dir_.path(), "rack-foxglove");
  ASSERT_TRUE(bridge.wait_for_stderr("(Foxglove WebSocket)", 15s)) << bridge.err();
  const std::string url = word_after(bridge.err(), "rack-foxglove: serving ");
  const RunResult r = run({*node_, kFoxglove + "/test/image_check.mjs", "--url", url, "--timeout", "30"}, 45s);
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.exit_code, 0) << r.describe() << "\nrack-foxglove:\n" << bridge.err() << logs();
  bridge.signal(SIGTERM);
  ASSERT_EQ(bridge.wait_exit(15s), std::optional<int>(0)) << bridge.err();
  const RunResult check = run({*node_, kFoxglove + "/test/mcap_check.mjs", file, "--topic", "/rack/0/camera/image"},
                              30s);
  std::printf("%s", check.out.c_str());
  EXPECT_EQ(check.exit_code, 0) << check.describe();
}

// Installed (issue 24): `cmake --install` of the Gui component puts bin/rack-foxglove and
// share/rack/foxglove (scripts and npm packages) in the prefix, with its bash
// completion; the installed program runs from there (--version names the installed
// packages, --help), whatever the working directory.
TEST_F(FoxgloveTest, InstalledTreeRunsRackFoxglove) {
  const auto prefix = dir_.path() / "prefix";
  for (const char* component : {"Gui", "Unspecified"}) {
    const RunResult r = run({kCmake, "--install", kBinaryDir, "--prefix", prefix.string(), "--component", component},
                            90s);
    ASSERT_EQ(r.exit_code, 0) << r.describe();
  }
  for (const char* file :
       {"bin/rack-foxglove", "share/rack/foxglove/rack-foxglove.mjs", "share/rack/foxglove/lib/player.mjs",
        "share/rack/foxglove/node_modules/@mcap/core/package.json",
        "share/bash-completion/completions/rack-foxglove"}) {
    EXPECT_TRUE(std::filesystem::exists(prefix / file)) << file;
  }
  const RunResult version = run({(prefix / "bin/rack-foxglove").string(), "--version"}, 30s);
  EXPECT_EQ(version.exit_code, 0) << version.describe();
  EXPECT_EQ(version.out.rfind("rack-foxglove ", 0), 0u) << version.out;
  EXPECT_NE(version.out.find("@mcap/core"), std::string::npos) << version.out;
  const RunResult help = run({(prefix / "bin/rack-foxglove").string(), "--help"}, 30s);
  EXPECT_EQ(help.exit_code, 0) << help.describe();
  EXPECT_NE(help.out.find("usage: rack-foxglove"), std::string::npos) << help.out;
  // Its own refusal of a bad argument, from the installed scripts.
  const RunResult bad = run({(prefix / "bin/rack-foxglove").string(), "--compression", "gzip", "--gui", "ws://x"}, 30s);
  EXPECT_EQ(bad.exit_code, 1) << bad.describe();
  EXPECT_NE(bad.err.find("--compression gzip"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace rack::test
