// Integration: the task timeline of configs/sim_mcl.yaml in the real rackd, recorded
// by the real rackctl over TiMS/LCM (`rackctl trace`), written as a Chrome JSON trace
// and parsed back: one track per task, cycles as complete events, wake-ups of the
// periodic tasks, message hand-offs joined by flow events.
// TraceLoaderTest reads the traces with a loader we did not write: the trace engine of
// Chrome DevTools' Performance panel (npm @paulirish/trace_engine, driven by
// tests/trace_check/load_trace.mjs under node).
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "mini_json.h"
#include "rack/core/trace_session.h"
#include "process.h"
#include "shipped_host.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kTraceCheck = RACK_TRACE_CHECK_DIR;  // tests/trace_check

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
    } else if (ph == "I") {
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
    if (ph == "I" && e.at("name").string == "wake-up") ++wakes[track];
    if (ph == "I" && contains(e.at("name").string, "send to ")) ++sends[track];
    if (ph == "I" && contains(e.at("name").string, "receive from ")) ++receives[track];
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

TEST_F(TraceTest, AnUnwritableOutIsSaidBeforeAnythingIsRecorded) {
  for (const std::string& out : {(dir_.path() / "no" / "such" / "dir.json").string(), dir_.path().string()}) {
    const RunResult r = ctl({"trace", "--duration", "0.2", "--out", out, "all"});
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    EXPECT_TRUE(contains(r.err, "--out " + out + ": cannot write")) << r.describe();
    EXPECT_FALSE(contains(r.err, "recording")) << "asked rackd to record: " << r.describe();
  }
  EXPECT_FALSE(std::filesystem::exists(dir_.path() / "no")) << "created a folder";
}

// ---------------------------------------------------------------- a loader we did not write

// What Chrome DevTools' trace engine made of a trace file (load_trace.mjs's summary),
// or the reason the test cannot run.
struct Loaded {
  std::optional<Json> summary;
  std::string skip;  // why the loader is not there
  RunResult run;
};
Loaded load_with_devtools(const std::filesystem::path& file) {
  Loaded l;
  const auto node = find_program("node");
  if (!node) {
    l.skip = "node is not installed (Debian: apt-get install nodejs; scripts/setup.sh installs it)";
    return l;
  }
  if (!std::filesystem::exists(kTraceCheck + "/node_modules/@paulirish/trace_engine/package.json")) {
    l.skip =
        "the trace engine is not installed: cd tests/trace_check && npm ci --no-audit --no-fund "
        "(scripts/setup.sh does it)";
    return l;
  }
  l.run = run({*node, kTraceCheck + "/load_trace.mjs", file.string()}, 60s);
  if (l.run.exit_code == 0) l.summary = parse_json(l.run.out);
  return l;
}

const Json* thread_named(const Json& summary, const std::string& name) {
  for (const auto& t : summary.at("threads").array) {
    if (t.at("name").string == name) return &t;
  }
  return nullptr;
}
double count_of(const Json& thread, const char* group, const std::string& name) {
  const Json* e = thread.at(group).get(name);
  if (e == nullptr) return 0;
  return e->is_number() ? e->number : e->at("count").number;
}
double count_prefixed(const Json& thread, const char* group, const std::string& prefix) {
  double n = 0;
  for (const auto& [name, v] : thread.at(group).object) {
    if (name.rfind(prefix, 0) == 0) n += v.is_number() ? v.number : v.at("count").number;
  }
  return n;
}

TEST_F(TraceTest, ChromeDevToolsTraceEngineLoadsTheTraceOfSimMcl) {
  const auto out = dir_.path() / "devtools.json";
  const RunResult r = ctl({"trace", "--duration", "1.5", "--out", out.string(), "all"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const Loaded l = load_with_devtools(out);
  if (!l.skip.empty()) GTEST_SKIP() << l.skip;
  ASSERT_TRUE(l.summary.has_value()) << l.run.describe();
  const Json& s = *l.summary;
  // Nothing said on the console while it parsed, no warning about the trace.
  EXPECT_TRUE(s.at("messages").array.empty()) << l.run.out;
  EXPECT_TRUE(s.at("warnings").object.empty()) << l.run.out;

  // The process: rackd's, named after the host.
  const double pid = host_.rackd().pid();
  ASSERT_EQ(s.at("processes").array.size(), 1u) << l.run.out;
  EXPECT_EQ(s.at("processes").array[0].at("pid").number, pid);
  EXPECT_TRUE(contains(s.at("processes").array[0].at("name").string, "sim")) << l.run.out;

  // Threads named after the tasks, each a live thread of that rackd. DevTools leaves
  // out a thread with no event: a command task that received no command meanwhile.
  EXPECT_GE(s.at("threads").array.size(), 9u) << l.run.out;
  EXPECT_LE(s.at("threads").array.size(), 18u) << l.run.out;
  std::set<double> tids;
  for (const auto& t : s.at("threads").array) {
    EXPECT_EQ(t.at("pid").number, pid);
    tids.insert(t.at("tid").number);
    const auto task = std::filesystem::path("/proc") / std::to_string(host_.rackd().pid()) / "task" /
                      std::to_string(static_cast<long>(t.at("tid").number));
    EXPECT_TRUE(std::filesystem::exists(task)) << t.at("name").string << ": no thread " << task;
  }
  EXPECT_EQ(tids.size(), s.at("threads").array.size()) << "one thread id per task";
  std::set<std::string> tasks;
  for (const char* c : {"chassis", "ladar", "odometry", "scan2d", "position", "path", "mcl", "pilot", "evaluator"}) {
    EXPECT_NE(thread_named(s, std::string(c) + " data task"), nullptr) << c;
    tasks.insert(std::string(c) + " data task");
    tasks.insert(std::string(c) + " command task");
  }
  for (const auto& t : s.at("threads").array) EXPECT_EQ(tasks.count(t.at("name").string), 1u) << t.at("name").string;
  // The chassis takes the pilot's MOVE commands (every 50 ms): its command task is there.
  EXPECT_NE(thread_named(s, "chassis command task"), nullptr);

  // Cycles as slices with their durations: the chassis at 100 Hz for 1.5 s, each
  // cycle shorter than its 10 ms period; wake-ups as instants.
  const Json* chassis = thread_named(s, "chassis data task");
  ASSERT_NE(chassis, nullptr);
  EXPECT_GE(count_of(*chassis, "slices", "loop"), 75);
  EXPECT_LE(count_of(*chassis, "slices", "loop"), 160);
  EXPECT_GE(chassis->at("slices").at("loop").at("min_dur_us").number, 0.0);
  EXPECT_LT(chassis->at("slices").at("loop").at("max_dur_us").number, 10'000.0);
  EXPECT_GE(count_of(*chassis, "instants", "wake-up"), 75);
  const Json* mcl = thread_named(s, "mcl data task");
  ASSERT_NE(mcl, nullptr);
  EXPECT_GT(count_of(*mcl, "slices", "loop"), 0);
  EXPECT_EQ(count_of(*mcl, "instants", "wake-up"), 0) << "MCL is triggered by its input";
  EXPECT_GT(count_prefixed(*mcl, "instants", "receive from "), 0);
  const Json* ladar = thread_named(s, "ladar data task");
  ASSERT_NE(ladar, nullptr);
  EXPECT_GT(count_prefixed(*ladar, "instants", "send to "), 0);

  // Hand-offs: the engine bound each flow to its send and its receive, on two threads.
  EXPECT_GT(s.at("flows").array.size(), 10u) << l.run.out;
  for (const auto& f : s.at("flows").array) {
    const auto& ev = f.at("events").array;
    ASSERT_EQ(ev.size(), 2u);
    EXPECT_TRUE(contains(ev[0].at("name").string, "send to ")) << ev[0].at("name").string;
    EXPECT_TRUE(contains(ev[1].at("name").string, "receive from ")) << ev[1].at("name").string;
    EXPECT_NE(ev[0].at("tid").number, ev[1].at("tid").number);
    EXPECT_LE(ev[0].at("ts").number, ev[1].at("ts").number);
  }
  // The trace spans its duration, in microseconds.
  EXPECT_GT(s.at("bounds_us").at("range").number, 1.0e6);
  EXPECT_LE(s.at("bounds_us").at("range").number, 1.6e6);
}

// Every kind of event the formatter writes, and the edges of a real trace: a ring that
// dropped events, a cycle that began before the trace, one still running when the host
// stopped, an end stamped before its start (a clock gone back), two events at the same
// instant, a receive whose send was not traced.
TEST(TraceLoaderTest, ChromeDevToolsTraceEngineLoadsEveryKindOfEvent) {
  using rt::trace::Event;
  using rt::trace::Kind;
  constexpr int64_t kUs = 1000;
  const int64_t t0 = 5'000'000'000;
  const auto ev = [&](int64_t us, Kind k, int64_t value = 0, uint32_t peer = 0, uint16_t aux = 0, uint32_t self = 0) {
    Event e;
    e.time_ns = t0 + us * kUs;
    e.kind = k;
    e.value = value;
    e.peer = peer;
    e.aux = aux;
    e.self = self;
    return e;
  };
  constexpr uint32_t kLadar = 0x00010100u, kMcl = 0x00020100u, kOther = 0x00030100u;
  const uint16_t msg = rt::trace::message_aux(10, 7);
  std::vector<trace::TaskTrace> tasks(2);
  tasks[0].track = "ladar data task";
  tasks[0].component = "ladar";
  tasks[0].tid = 101;
  tasks[0].dropped = 12;
  tasks[0].events = {ev(5, Kind::kCycleEnd),  // its start came before the trace
                     ev(100, Kind::kWake, t0 + 90 * kUs),
                     ev(101, Kind::kCycleStart),
                     ev(150, Kind::kSend, 0, kMcl, msg, kLadar),
                     ev(200, Kind::kOverrun, 2),
                     ev(200, Kind::kModeSwitch, 1),
                     ev(300, Kind::kCycleEnd, 1),
                     ev(400, Kind::kCycleStart),
                     ev(390, Kind::kCycleEnd),     // a clock gone back
                     ev(500, Kind::kCycleStart)};  // the host stopped mid-cycle
  tasks[1].track = "mcl data task";
  tasks[1].component = "mcl";
  tasks[1].tid = 102;
  tasks[1].sort_index = 1;
  tasks[1].events = {ev(160, Kind::kCycleStart), ev(170, Kind::kReceive, 0, kLadar, msg, kMcl),
                     ev(175, Kind::kReceive, 0, kOther, msg, kMcl), ev(250, Kind::kCycleEnd)};
  trace::TraceFormat f;
  f.pid = 4242;
  f.process_name = "rackd host 'edges'";
  f.origin_ns = t0;
  f.duration_ns = 600 * kUs;
  f.dropped = 12;
  TempDir dir;
  const auto file = dir.write("edges.json", trace::format_chrome_trace(tasks, f));

  const Loaded l = load_with_devtools(file);
  if (!l.skip.empty()) GTEST_SKIP() << l.skip;
  ASSERT_TRUE(l.summary.has_value()) << l.run.describe();
  const Json& s = *l.summary;
  EXPECT_TRUE(s.at("messages").array.empty()) << l.run.out;
  EXPECT_TRUE(s.at("warnings").object.empty()) << l.run.out;
  ASSERT_EQ(s.at("processes").array.size(), 1u);
  EXPECT_EQ(s.at("processes").array[0].at("name").string, "rackd host 'edges'");
  const Json* ladar = thread_named(s, "ladar data task");
  const Json* mcl = thread_named(s, "mcl data task");
  ASSERT_NE(ladar, nullptr) << l.run.out;
  ASSERT_NE(mcl, nullptr) << l.run.out;
  EXPECT_EQ(ladar->at("tid").number, 101);
  // One whole cycle each: 199 us and 90 us; the others are left out, never negative.
  EXPECT_EQ(count_of(*ladar, "slices", "loop"), 1);
  EXPECT_DOUBLE_EQ(ladar->at("slices").at("loop").at("min_dur_us").number, 199.0);
  EXPECT_EQ(count_of(*mcl, "slices", "loop"), 1);
  EXPECT_DOUBLE_EQ(mcl->at("slices").at("loop").at("max_dur_us").number, 90.0);
  EXPECT_EQ(count_of(*ladar, "instants", "wake-up"), 1);
  EXPECT_EQ(count_of(*ladar, "instants", "overrun"), 1);
  EXPECT_EQ(count_of(*ladar, "instants", "mode switch"), 1);
  EXPECT_EQ(count_of(*ladar, "instants", "events dropped (ring full)"), 1);
  EXPECT_EQ(count_prefixed(*ladar, "instants", "send to "), 1);
  EXPECT_EQ(count_prefixed(*mcl, "instants", "receive from "), 2);
  ASSERT_EQ(s.at("flows").array.size(), 1u) << l.run.out;
  const auto& flow = s.at("flows").array[0].at("events").array;
  ASSERT_EQ(flow.size(), 2u);
  EXPECT_EQ(flow[0].at("tid").number, 101);
  EXPECT_DOUBLE_EQ(flow[0].at("ts").number, 150.0);
  EXPECT_EQ(flow[1].at("tid").number, 102);
  EXPECT_DOUBLE_EQ(flow[1].at("ts").number, 170.0);
}

}  // namespace
}  // namespace rack::test
