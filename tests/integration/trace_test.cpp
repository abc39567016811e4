// Integration: the task timeline of configs/sim_mcl.yaml in the real rackd, recorded
// by the real rackctl over TiMS/LCM (`rackctl trace`), written as a Chrome JSON trace
// and parsed back: one track per task, cycles as complete events, wake-ups of the
// periodic tasks, message hand-offs joined by flow events.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "shipped_host.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class TraceTest : public ::testing::Test {
 protected:
  TraceTest() : watchdog_(60s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void SetUp() override {
    const auto classes = run({kRackd, "--list-classes"}, 30s);
    ASSERT_EQ(classes.exit_code, 0) << classes.describe();
    if (!contains(classes.out, "MCL  (class ")) GTEST_SKIP() << "class MCL is not built into this rackd";
    ASSERT_TRUE(host_.start(host_.write("sim_mcl.yaml", shipped_host_text("sim_mcl.yaml"))));
  }
  RunResult ctl(std::vector<std::string> args) { return host_.ctl(std::move(args)); }

  Watchdog watchdog_;
  RackdOnBus host_;  // stopped (SIGTERM, exit 0) when the test ends
  const TempDir& dir_ = host_.dir();
};

TEST_F(TraceTest, RecordsEveryTaskOfSimMclAndTheJsonReadsBack) {
  const auto out = dir_.path() / "sim_mcl.json";
  const RunResult r = ctl({"trace", "--duration", "1.5", "--out", out.string(), "all"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "18 task(s) of host")) << r.describe();
  const auto doc = parse_json(read_file(out));
  ASSERT_TRUE(doc.has_value()) << "not JSON";
  const Json& events = doc->at("traceEvents");
  ASSERT_EQ(events.type, Json::Type::kArray);
  EXPECT_NEAR(doc->at("otherData").at("duration_s").number, 1.5, 0.1);

  // Every event has the fields of its phase (the Trace Event Format's schema).
  std::map<double, std::string> track_of;  // tid -> track name
  for (const auto& e : events.array) {
    ASSERT_TRUE(e.at("ph").is_string() && e.at("name").is_string() && e.at("pid").is_number() &&
                e.at("tid").is_number());
    const std::string& ph = e.at("ph").string;
    if (ph == "M" && e.at("name").string == "thread_name")
      track_of[e.at("tid").number] = e.at("args").at("name").string;
    if (ph == "X") {
      ASSERT_TRUE(e.at("ts").is_number() && e.at("dur").is_number() && e.at("dur").number >= 0);
    } else if (ph == "i") {
      ASSERT_TRUE(e.at("ts").is_number() && e.at("s").string == "t");
    } else if (ph == "s" || ph == "f") {
      ASSERT_TRUE(e.at("id").is_number() && e.at("ts").is_number());
    } else {
      ASSERT_EQ(ph, "M");
    }
  }
  std::set<std::string> tracks;
  for (const auto& [tid, name] : track_of) tracks.insert(name);
  for (const char* c : {"chassis", "ladar", "odometry", "scan2d", "position", "path", "mcl", "pilot", "evaluator"}) {
    EXPECT_EQ(tracks.count(std::string(c) + " command task"), 1u) << c;
    EXPECT_EQ(tracks.count(std::string(c) + " data task"), 1u) << c;
  }
  EXPECT_EQ(track_of.size(), 18u) << "one distinct thread id per task";

  // Cycles: per track in time order and never overlapping; the periodic tasks woke
  // up and ran at their rates (chassis 100 Hz, ladar 25 Hz) with their wake-up latency.
  std::map<std::string, std::vector<std::pair<double, double>>> cycles;  // track -> (ts, end)
  std::map<std::string, int> wakes, sends, receives;
  std::map<std::string, bool> latency_given;
  for (const auto& e : events.array) {
    const std::string& track = track_of[e.at("tid").number];
    const std::string& ph = e.at("ph").string;
    if (ph == "X") {
      cycles[track].emplace_back(e.at("ts").number, e.at("ts").number + e.at("dur").number);
      if (e.at("args").at("wake_latency_us").is_number()) {
        EXPECT_GE(e.at("args").at("wake_latency_us").number, 0.0);
        latency_given[track] = true;
      }
    }
    if (ph == "i" && e.at("name").string == "wake-up") ++wakes[track];
    if (ph == "i" && contains(e.at("name").string, "send to ")) ++sends[track];
    if (ph == "i" && contains(e.at("name").string, "receive from ")) ++receives[track];
  }
  for (const auto& [track, list] : cycles) {
    for (std::size_t i = 1; i < list.size(); ++i) {
      ASSERT_LE(list[i - 1].second, list[i].first + 1e-3) << track << " cycle " << i;
    }
  }
  // 1.5 s: 150 chassis periods, 37 ladar periods (bounds leave room for a busy machine).
  EXPECT_GE(cycles["chassis data task"].size(), 75u);
  EXPECT_LE(cycles["chassis data task"].size(), 160u);
  EXPECT_GE(wakes["chassis data task"], 75);
  EXPECT_GE(cycles["ladar data task"].size(), 18u);
  EXPECT_LE(cycles["ladar data task"].size(), 40u);
  EXPECT_TRUE(latency_given["ladar data task"]);
  EXPECT_EQ(wakes["mcl data task"], 0) << "MCL is triggered by its input, not periodic";
  EXPECT_GT(cycles["mcl data task"].size(), 0u);
  // Hand-offs: the ladar publishes to its listeners; MCL takes its input.
  EXPECT_GT(sends["ladar data task"], 0);
  EXPECT_GT(receives["mcl data task"], 0);

  // Flows: every start has its end, on another track, not earlier.
  std::map<double, std::pair<const Json*, const Json*>> flows;
  for (const auto& e : events.array) {
    if (e.at("ph").string == "s") flows[e.at("id").number].first = &e;
    if (e.at("ph").string == "f") flows[e.at("id").number].second = &e;
  }
  EXPECT_GT(flows.size(), 10u);
  for (const auto& [id, pair] : flows) {
    ASSERT_NE(pair.first, nullptr) << id;
    ASSERT_NE(pair.second, nullptr) << id;
    EXPECT_LE(pair.first->at("ts").number, pair.second->at("ts").number) << id;
  }
}

TEST_F(TraceTest, NamedComponentsOnlyAndTheCommandLineIsChecked) {
  const auto out = dir_.path() / "mcl.json";
  RunResult r = ctl({"trace", "--duration", "0.3", "--out", out.string(), "mcl,ladar"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto doc = parse_json(read_file(out));
  ASSERT_TRUE(doc.has_value());
  std::set<std::string> tracks;
  for (const auto& e : doc->at("traceEvents").array) {
    if (e.at("name").string == "thread_name") tracks.insert(e.at("args").at("name").string);
  }
  EXPECT_EQ(tracks,
            (std::set<std::string>{"ladar command task", "ladar data task", "mcl command task", "mcl data task"}));

  r = ctl({"trace", "--duration", "0", "--out", out.string()});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  r = ctl({"trace", "--duration", "1"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "--out")) << r.describe();
  r = ctl({"--discover-ms", "300", "trace", "--duration", "1", "--out", out.string(), "nosuch"});
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "nosuch")) << r.describe();
}

}  // namespace
}  // namespace rack::test
