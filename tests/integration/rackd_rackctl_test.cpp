// Integration tests: the real rackd binary, driven by the real rackctl binary over
// TiMS/LCM, as an operator would. Each test has its own LCM bus (a port of its own),
// its own temporary directory and a watchdog; every child dies with the test.
//
// The tests assert behaviour (exit codes, states, messages, data), never timings:
// waits are bounded generously and only make a hang fail instead of blocking.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <sstream>
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

constexpr auto kTestLimit = 100s;    // the watchdog (ctest's own TIMEOUT is 120 s)
constexpr auto kCommandLimit = 30s;  // one rackd --check or rackctl run
constexpr auto kStartLimit = 30s;    // rackd until "running"
constexpr auto kSettleLimit = 20s;   // a state change we wait for

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// ------------------------------------------------------------------ base fixture

class IntegrationTest : public ::testing::Test {
 protected:
  IntegrationTest() : watchdog_(kTestLimit, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  RunResult rackd(std::vector<std::string> args) {
    args.insert(args.begin(), kRackd);
    return run(args, kCommandLimit);
  }

  // rackctl on this test's bus. Name look-ups stop as soon as the name is found, so a
  // generous --discover-ms costs nothing unless the name is unknown (or for list).
  RunResult ctl(std::vector<std::string> args, const std::string& discover_ms = "3000") {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url(), "--discover-ms", discover_ms});
    return run(args, kCommandLimit);
  }

  // Starts rackd on this test's bus and waits until it runs.
  std::unique_ptr<Process> start_rackd(const std::string& host_file) {
    auto p = std::make_unique<Process>(std::vector<std::string>{kRackd, host_file, "--lcm", bus_.url()}, dir_.path(),
                                       "rackd");
    if (!p->wait_for_stderr("rackd: running", kStartLimit)) {
      ADD_FAILURE() << "rackd did not start:\n" << p->err();
      return nullptr;
    }
    return p;
  }

  // GET_STATUS + GET_STATS of one component as JSON (null on failure).
  std::optional<Json> status_json(const std::string& name) {
    const RunResult r = ctl({"status", name, "--json"});
    if (r.exit_code != 0) return std::nullopt;
    return parse_json(r.out);
  }
  std::string state_of(const std::string& name) {
    const auto j = status_json(name);
    const Json* s = j ? j->get("state") : nullptr;
    return s != nullptr && s->is_string() ? s->string : "";
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
};

// ------------------------------------------------------------------ rackd --check

using RackdCheckTest = IntegrationTest;

TEST_F(RackdCheckTest, DemoHostFileIsValid) {
  const RunResult r = rackd({"--check", kConfigs + "/demo.yaml"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "valid")) << r.describe();
}

TEST_F(RackdCheckTest, MissingFileExits2) {
  const std::string path = (dir_.path() / "no-such-host.yaml").string();
  const RunResult r = rackd({"--check", path});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, path + ": cannot read the host file")) << r.describe();
  EXPECT_TRUE(contains(r.err, "nothing started")) << r.describe();
}

// A valid host file; each malformed case changes a line or two. The line that the
// error must name carries the marker "# <-- error".
constexpr const char* kValidHost = R"(host: it-check
system: 0
lcm: false
heap_prefault_mib: 0
components:
  - name: generator
    class: Generator
    instance: 0
    command_task:
      priority: 30
    data_task:
      priority: 60
      period_ms: 10
    params:
      amplitude: 2.0
  - name: monitor
    class: Monitor
    instance: 0
    params:
      source: generator
)";
constexpr const char* kMarker = "# <-- error";

struct MalformedCase {
  const char* name;
  std::vector<std::pair<std::string, std::string>> edits;  // first occurrence of a line -> text
  const char* append;                                      // added at the end
  const char* message;                                     // part of the error message
};

// gtest prints the case by name (instead of its bytes).
void PrintTo(const MalformedCase& c, std::ostream* os) { *os << c.name; }

std::string apply(const MalformedCase& c) {
  std::string text = kValidHost;
  for (const auto& [from, to] : c.edits) {
    const auto at = text.find(from + "\n");
    if (at == std::string::npos) throw std::logic_error(std::string("bad test case ") + c.name + ": " + from);
    text.replace(at, from.size(), to);
  }
  return text + c.append;
}

int marked_line(const std::string& text) {
  const auto lines = [&] {
    std::vector<std::string> v;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) v.push_back(l);
    return v;
  }();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (contains(lines[i], kMarker)) return static_cast<int>(i + 1);
  }
  return 0;
}

class HostFileErrorTest : public IntegrationTest, public ::testing::WithParamInterface<MalformedCase> {};

TEST_P(HostFileErrorTest, ExitsTwoWithFileLineColumnAndStartsNothing) {
  const MalformedCase& c = GetParam();
  const std::string text = apply(c);
  const int line = marked_line(text);
  ASSERT_GT(line, 0) << "test case without marker";
  const std::string path = dir_.write(std::string(c.name) + ".yaml", text).string();

  const RunResult check = rackd({"--check", path});
  EXPECT_EQ(check.exit_code, 2) << check.describe();
  // The error names the offending line: "file:line:col: message".
  bool found = false;
  for (const auto& l : lines_of(check.err)) {
    if (!contains(l, c.message)) continue;
    found = true;
    EXPECT_EQ(l.rfind(path + ":" + std::to_string(line) + ":", 0), 0u)
        << "expected " << path << ":" << line << ":col: ... in\n"
        << l << "\nfile:\n"
        << text;
  }
  EXPECT_TRUE(found) << "no error containing '" << c.message << "':\n" << check.describe() << "\nfile:\n" << text;
  EXPECT_TRUE(contains(check.err, "nothing started")) << check.describe();

  // Without --check: refuses to start, and never reaches "running".
  const RunResult start = rackd({path, "--lcm", bus_.url()});
  EXPECT_EQ(start.exit_code, 2) << start.describe();
  EXPECT_FALSE(contains(start.err, "rackd: running")) << start.describe();
  EXPECT_TRUE(contains(start.err, "nothing started")) << start.describe();
}

const MalformedCase kMalformed[] = {
    {"unknown_key",
     {{"    instance: 0", "    instance: 0\n    colour: blue  # <-- error"}},
     "",
     "unknown key 'colour'"},
    {"wrong_type_priority",
     {{"      priority: 60", "      priority: \"high\"  # <-- error"}},
     "",
     "'priority' must be"},
    {"missing_required_parameter",
     {{"      source: generator", "      source_period_ms: 100"},
      {"  - name: monitor", "  - name: monitor  # <-- error"}},
     "",
     "missing required parameter 'source'"},
    {"unknown_parameter",
     {{"      amplitude: 2.0", "      amplitude: 2.0\n      colour: 3  # <-- error"}},
     "",
     "unknown parameter 'colour'"},
    {"unknown_class",
     {{"    class: Generator", "    class: Generatr  # <-- error"}},
     "",
     "unknown component class 'Generatr'"},
    {"duplicate_address",
     {},
     "  - name: generator2  # <-- error\n    class: Generator\n    instance: 0\n    data_task: {period_ms: 10}\n",
     "has the address Generator(0/0)"},
    // A data task may have priority 0 (normal scheduling, for heavy components such as
    // MCL); below that, or above 99, is an error.
    {"priority_negative",
     {{"      priority: 60", "      priority: -1  # <-- error"}},
     "",
     "'priority' = -1 is outside 0..99"},
    {"priority_100",
     {{"      priority: 60", "      priority: 100  # <-- error"}},
     "",
     "'priority' = 100 is outside 0..99"},
    {"cpu_not_online",
     {{"      priority: 60", "      priority: 60\n      cpu: 999  # <-- error"}},
     "",
     "CPU 999 is not online"},
    {"period_zero", {{"      period_ms: 10", "      period_ms: 0  # <-- error"}}, "", "'period_ms' must be positive"},
    {"period_negative",
     {{"      period_ms: 10", "      period_ms: -5  # <-- error"}},
     "",
     "'period_ms' must be positive"},
    {"yaml_syntax", {{"      period_ms: 10", "      period_ms: 10: 5  # <-- error"}}, "", "YAML syntax"},
};

INSTANTIATE_TEST_SUITE_P(Malformed, HostFileErrorTest, ::testing::ValuesIn(kMalformed),
                         [](const ::testing::TestParamInfo<MalformedCase>& param_info) {
                           return param_info.param.name;
                         });

// ------------------------------------------------------------------ rackctl alone

using RackctlTest = IntegrationTest;

TEST_F(RackctlTest, HelpAndUsageErrors) {
  RunResult r = ctl({"--help"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "usage: rackctl")) << r.describe();
  r = ctl({"help", "watch"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "watch NAME")) << r.describe();
  r = ctl({"set-param", "--help"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "set-param NAME KEY VALUE")) << r.describe();
  EXPECT_EQ(ctl({}).exit_code, 2);
  EXPECT_EQ(ctl({"frobnicate"}).exit_code, 2);
  EXPECT_EQ(ctl({"on"}).exit_code, 2);
  EXPECT_EQ(ctl({"on", "a", "b"}).exit_code, 2);
  EXPECT_EQ(ctl({"on", "generator", "--count", "3"}).exit_code, 2);
  EXPECT_EQ(ctl({"status", "generator", "--timeout", "soon"}).exit_code, 2);
  EXPECT_EQ(ctl({"status", "Generator(0/"}).exit_code, 2);
}

TEST_F(RackctlTest, WithoutRackdEverythingIsNotAvailable) {
  RunResult r = ctl({"status", "generator"}, "300");
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "generator")) << r.describe();
  // rackctl knows no class: Generator(0/0) is the component whose class describes
  // itself so, and nothing answers discovery to say which that is.
  r = ctl({"--timeout", "300", "status", "Generator(0/0)"});
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "no component of a class named 'Generator' at system 0, instance 0 answered discovery"))
      << r.describe();
  r = ctl({"--timeout", "300", "status", "Class0x10(0/0)"});  // by class id: sent, not answered
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "no reply")) << r.describe();
  r = ctl({"list"}, "300");
  EXPECT_EQ(r.exit_code, 3) << r.describe();
}

// ------------------------------------------------------------------ the demo host

class RackdDemoTest : public IntegrationTest {
 protected:
  void SetUp() override {
    rackd_ = start_rackd(kConfigs + "/demo.yaml");
    ASSERT_NE(rackd_, nullptr);
  }
  void TearDown() override {
    if (rackd_ && rackd_->running()) {
      rackd_->signal(SIGTERM);
      const auto code = rackd_->wait_exit(kCommandLimit);
      EXPECT_EQ(code, std::optional<int>(0)) << rackd_->err();
    }
  }
  // `component`'s parameter `name` as `rackctl params --json` gives it; nullopt when
  // rackctl fails (a failure of the test too) or does not list it.
  std::optional<double> param_value(const std::string& component, const std::string& name) {
    const RunResult r = ctl({"params", component, "--json"});
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    const auto params = parse_json(r.out);
    EXPECT_TRUE(params.has_value()) << r.out;
    if (params) {
      for (const auto& p : params->array) {
        if (p.at("name").string == name) return p.at("value").number;
      }
    }
    return std::nullopt;
  }
  std::unique_ptr<Process> rackd_;
};

TEST_F(RackdDemoTest, ListShowsBothComponentsEnabled) {
  // The monitor switched the generator on (cascading ON) at autostart.
  ASSERT_TRUE(eventually([&] { return state_of("monitor") == "ENABLED"; }));
  const RunResult r = ctl({"list"}, "1000");
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto lines = lines_of(r.out);
  ASSERT_GE(lines.size(), 3u) << r.describe();
  EXPECT_TRUE(contains(lines[0], "ADDRESS") && contains(lines[0], "STATE")) << r.describe();
  bool generator = false, monitor = false;
  for (const auto& l : lines) {
    std::istringstream in(l);
    std::string address, name, cls, state;
    in >> address >> name >> cls >> state;
    if (address == "Generator(0/0)") {
      generator = true;
      EXPECT_EQ(name, "generator");
      EXPECT_EQ(state, "ENABLED") << l;
      EXPECT_TRUE(contains(l, "demo")) << l;
    }
    if (address == "Monitor(0/0)") {
      monitor = true;
      EXPECT_EQ(name, "monitor");
      EXPECT_EQ(state, "ENABLED") << l;
    }
  }
  EXPECT_TRUE(generator && monitor) << r.describe();
}

TEST_F(RackdDemoTest, StatusShowsCycles) {
  // Cycles of the triggered monitor count the samples it received.
  ASSERT_TRUE(eventually([&] {
    const auto j = status_json("monitor");
    const Json* c = j ? j->get("cycles") : nullptr;
    return c != nullptr && c->is_number() && c->number > 0;
  }));
  const RunResult r = ctl({"status", "monitor"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "Monitor(0/0)")) << r.describe();
  EXPECT_TRUE(contains(r.out, "cycles")) << r.describe();
  EXPECT_TRUE(contains(r.out, "ENABLED")) << r.describe();

  const auto j = status_json("generator");
  ASSERT_TRUE(j.has_value());
  for (const char* key : {"state", "data_task", "period_ns", "cycles", "overruns", "latency_us", "published",
                          "listeners", "listener_drops", "malformed", "commands"}) {
    EXPECT_NE(j->get(key), nullptr) << key;
  }
  EXPECT_EQ(j->at("data_task").string, "periodic");
  EXPECT_EQ(j->at("period_ns").number, 10e6);
  EXPECT_GE(j->at("listeners").number, 1.0);  // the monitor
}

// GET_LATENCY through rackd and rackctl: the running generator's (periodic, 10 ms)
// histogram. Sandwiched between two GET_STATS, its sample count lies between theirs
// (all three count the same monotonic 1-us histogram), and its buckets add up to it.
TEST_F(RackdDemoTest, LatencyHistogramMatchesTheStatsOfARunningGenerator) {
  ASSERT_TRUE(eventually([&] {
    const auto j = status_json("generator");
    return j && j->at("latency_us").at("samples").number >= 10;
  }));
  const auto before = status_json("generator");
  const RunResult r = ctl({"latency", "generator", "--json"});
  const auto after = status_json("generator");
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  ASSERT_TRUE(before && after);
  const auto j = parse_json(r.out);
  ASSERT_TRUE(j.has_value()) << r.out;
  EXPECT_EQ(j->at("component").string, "Generator(0/0)");
  EXPECT_EQ(j->at("data_task").string, "periodic");
  EXPECT_EQ(j->at("period_ns").number, 10e6);
  const double samples = j->at("samples").number;
  EXPECT_GE(samples, before->at("latency_us").at("samples").number);
  EXPECT_LE(samples, after->at("latency_us").at("samples").number);
  const auto& buckets = j->at("buckets").array;
  ASSERT_EQ(buckets.size(), 40u) << r.out;
  double sum = 0;
  int nonzero = 0;
  for (std::size_t i = 0; i < buckets.size(); ++i) {
    sum += buckets[i].at("count").number;
    nonzero += buckets[i].at("count").number > 0 ? 1 : 0;
    if (i + 1 < buckets.size()) {
      EXPECT_EQ(buckets[i].at("upper_ns").number, buckets[i + 1].at("lower_ns").number) << i;
    }
  }
  EXPECT_EQ(buckets.front().at("lower_ns").number, 0.0);
  EXPECT_TRUE(buckets.back().at("upper_ns").is_null()) << "the last bucket is open";
  EXPECT_EQ(buckets.back().at("lower_ns").number, 10e6);
  EXPECT_EQ(sum, samples);
  EXPECT_GT(nonzero, 0);

  // The text form: the header, the percentiles and at least one bar.
  const RunResult t = ctl({"latency", "generator"});
  ASSERT_EQ(t.exit_code, 0) << t.describe();
  EXPECT_TRUE(contains(t.out, "generator Generator(0/0): wake-up latency of the data task (periodic, period 10 ms)"))
      << t.out;
  EXPECT_TRUE(contains(t.out, "overruns")) << t.out;
  EXPECT_TRUE(contains(t.out, "p99.9")) << t.out;
  EXPECT_TRUE(contains(t.out, "LATENCY") && contains(t.out, "COUNT")) << t.out;
  EXPECT_TRUE(contains(t.out, "#")) << t.out;  // a bar
  const RunResult help = ctl({"help", "latency"});
  EXPECT_EQ(help.exit_code, 0) << help.describe();
  EXPECT_TRUE(contains(help.out, "latency NAME [--json]")) << help.out;
  EXPECT_EQ(ctl({"latency"}).exit_code, 2);
}

TEST_F(RackdDemoTest, OffGeneratorSendsMonitorToErrorAndItRecovers) {
  ASSERT_TRUE(eventually([&] { return state_of("Monitor(0/0)") == "ENABLED"; }));
  const auto before = status_json("Monitor(0/0)");
  ASSERT_TRUE(before.has_value());
  const double errors_before = before->at("errors").number;

  RunResult r = ctl({"off", "generator"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  // The generator dropped its listeners with an ERROR message: the monitor goes to
  // ERROR. (Its retry switches the generator on again after retry_ms, so the ERROR
  // may already be over when we look: its error counter shows it happened.)
  EXPECT_TRUE(eventually([&] {
    const auto j = status_json("Monitor(0/0)");
    return j && (j->at("state").string == "ERROR" || j->at("errors").number > errors_before);
  })) << "the monitor never went to ERROR";

  r = ctl({"on", "generator"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  // The monitor recovers by itself (retry, re-subscribe).
  EXPECT_TRUE(eventually([&] {
    return state_of("Monitor(0/0)") == "ENABLED" && state_of("Generator(0/0)") == "ENABLED";
  })) << "monitor "
      << state_of("Monitor(0/0)") << ", generator " << state_of("Generator(0/0)");
  // ... and receives data again.
  r = ctl({"watch", "monitor", "--count", "1"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

TEST_F(RackdDemoTest, ParamsAndSetParam) {
  RunResult r = ctl({"params", "generator"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  bool amplitude = false;
  for (const auto& l : lines_of(r.out)) {
    std::istringstream in(l);
    std::string name, kind, value;
    in >> name >> kind >> value;
    if (name != "amplitude") continue;
    amplitude = true;
    EXPECT_EQ(kind, "float");
    EXPECT_EQ(value, "2");  // from demo.yaml
  }
  EXPECT_TRUE(amplitude) << r.describe();
  EXPECT_TRUE(contains(r.out, "frequency_hz")) << r.describe();

  r = ctl({"set-param", "generator", "amplitude", "5"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_EQ(param_value("generator", "amplitude"), std::optional<double>(5.0));
  r = ctl({"get-data", "generator"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto sample = parse_json(r.out);
  ASSERT_TRUE(sample.has_value()) << r.out;
  EXPECT_LE(std::fabs(sample->at("data").at("value").number), 5.0) << r.out;

  // A small amplitude shows in the samples published after the change (the first
  // one may have been computed just before it).
  r = ctl({"set-param", "generator", "amplitude", "0.25"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  r = ctl({"watch", "generator", "--count", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 3u) << r.describe();
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto j = parse_json(lines[i]);
    ASSERT_TRUE(j.has_value()) << lines[i];
    EXPECT_LE(std::fabs(j->at("data").at("value").number), 0.25) << lines[i];
  }
}

TEST_F(RackdDemoTest, SetParamRejectsUnparsableValue) {
  const RunResult r = ctl({"set-param", "generator", "amplitude", "abc"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "abc")) << r.describe();
  EXPECT_TRUE(contains(r.err, "amplitude")) << r.describe();
  const RunResult b = ctl({"set-param", "monitor", "source_period_ms", "true"});
  EXPECT_EQ(b.exit_code, 2) << b.describe();
}

TEST_F(RackdDemoTest, SetParamUnknownParameterIsRefused) {
  const RunResult r = ctl({"set-param", "generator", "nosuch", "1"});
  EXPECT_TRUE(r.exit_code == 1 || r.exit_code == 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "unknown parameter 'nosuch'")) << r.describe();
}

// A parameter's former name works as in the host file (docs/parameters.md): the new
// parameter is set, and a warning on stderr names it.
TEST_F(RackdDemoTest, SetParamByAFormerNameSetsTheNewOneWithAWarning) {
  RunResult r = ctl({"set-param", "monitor", "period_ms", "50"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "source_period_ms = 50")) << r.describe();
  EXPECT_TRUE(contains(r.err, "warning: parameter 'period_ms' is now 'source_period_ms'")) << r.describe();
  EXPECT_EQ(param_value("monitor", "source_period_ms"), std::optional<double>(50.0));
  // By its own name: no warning.
  r = ctl({"set-param", "monitor", "source_period_ms", "100"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_FALSE(contains(r.err, "warning")) << r.describe();
}

TEST_F(RackdDemoTest, SetParamOutOfRangeShowsTheComponentsReason) {
  // frequency_hz is declared 0..1e4: the component answers ERROR with its reason.
  const RunResult r = ctl({"set-param", "generator", "frequency_hz", "-1"});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "out of range")) << r.describe();
}

TEST_F(RackdDemoTest, GetDataPrintsOneJsonLine) {
  // The generator has published once the monitor is ENABLED (it subscribed to it).
  ASSERT_TRUE(eventually([&] { return ctl({"get-data", "generator"}).exit_code == 0; }));
  const RunResult r = ctl({"get-data", "generator"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 1u) << r.describe();
  const auto j = parse_json(lines[0]);
  ASSERT_TRUE(j.has_value()) << lines[0];
  EXPECT_EQ(j->at("component").string, "Generator(0/0)");
  EXPECT_EQ(j->at("name").string, "generator");
  EXPECT_TRUE(j->at("time_ns").is_number());
  EXPECT_TRUE(j->at("sequence").is_number());
  ASSERT_NE(j->get("data"), nullptr) << lines[0];
  EXPECT_TRUE(j->at("data").at("value").is_number()) << lines[0];
  EXPECT_TRUE(j->at("data").at("counter").is_number()) << lines[0];

  // By address, and a time long before the oldest sample: the component's reason.
  EXPECT_EQ(ctl({"get-data", "Generator(0/0)"}).exit_code, 0);
  const RunResult old = ctl({"get-data", "generator", "--time", "1"});
  EXPECT_EQ(old.exit_code, 1) << old.describe();
  EXPECT_TRUE(contains(old.err, "older than the oldest sample")) << old.describe();
}

TEST_F(RackdDemoTest, WatchMonitorPrintsThreeJsonLines) {
  ASSERT_TRUE(eventually([&] { return state_of("monitor") == "ENABLED"; }));
  const RunResult r = ctl({"watch", "monitor", "--count", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 3u) << r.describe();
  double last_sequence = -1;
  for (const auto& l : lines) {
    const auto j = parse_json(l);
    ASSERT_TRUE(j.has_value()) << l;
    EXPECT_EQ(j->at("component").string, "Monitor(0/0)");
    ASSERT_NE(j->get("data"), nullptr) << l;
    EXPECT_TRUE(j->at("data").at("received").is_number()) << l;
    EXPECT_GT(j->at("sequence").number, last_sequence) << l;
    last_sequence = j->at("sequence").number;
  }
  EXPECT_TRUE(contains(r.err, "period")) << r.describe();
  // The watch unsubscribed on its way out: only the monitor listens to the generator,
  // and nobody to the monitor.
  const auto j = status_json("monitor");
  ASSERT_TRUE(j.has_value());
  EXPECT_EQ(j->at("listeners").number, 0.0);
}

TEST_F(RackdDemoTest, WatchEndsWithErrorWhenTheProducerGoesOff) {
  ASSERT_TRUE(eventually([&] { return state_of("Monitor(0/0)") == "ENABLED"; }));
  // Switch the monitor off while a watch runs: the watch gets the producer's ERROR.
  auto watch = std::make_unique<Process>(
      std::vector<std::string>{kRackctl, "--lcm", bus_.url(), "watch", "Monitor(0/0)"}, dir_.path(), "watch");
  ASSERT_TRUE(watch->wait_for_stderr("watching", kStartLimit)) << watch->err();
  EXPECT_EQ(ctl({"off", "monitor"}).exit_code, 0);
  const auto code = watch->wait_exit(kSettleLimit);
  EXPECT_EQ(code, std::optional<int>(1)) << watch->err();
  EXPECT_TRUE(contains(watch->err(), "left ENABLED")) << watch->err();
}

TEST_F(RackdDemoTest, WatchStopsOnSigint) {
  auto watch = std::make_unique<Process>(
      std::vector<std::string>{kRackctl, "--lcm", bus_.url(), "watch", "Generator(0/0)"}, dir_.path(), "watch");
  ASSERT_TRUE(watch->wait_for_stderr("watching", kStartLimit)) << watch->err();
  ASSERT_TRUE(eventually([&] { return !watch->out().empty(); }));
  watch->signal(SIGINT);
  EXPECT_EQ(watch->wait_exit(kSettleLimit), std::optional<int>(0)) << watch->err();
  for (const auto& l : lines_of(watch->out())) {
    // The last line may be cut only if the process died mid-write; it did not.
    EXPECT_TRUE(parse_json(l).has_value()) << l;
  }
  // STOP_CONT_DATA was sent: the monitor is the generator's only listener again.
  EXPECT_TRUE(eventually([&] {
    const auto j = status_json("Generator(0/0)");
    return j && j->at("listeners").number == 1.0;
  }));
}

TEST_F(RackdDemoTest, UnknownInstanceIsNotAvailable) {
  const RunResult r = ctl({"status", "Generator(0/9)"});
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "NOT_AVAILABLE")) << r.describe();
}

TEST_F(RackdDemoTest, UnknownNameIsNotAvailable) {
  const RunResult r = ctl({"status", "nosuchname"}, "1000");
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "nosuchname")) << r.describe();
}

TEST_F(RackdDemoTest, SigtermStopsCleanly) {
  rackd_->signal(SIGTERM);
  const auto code = rackd_->wait_exit(kSettleLimit);
  ASSERT_TRUE(code.has_value()) << "rackd still running after SIGTERM:\n" << rackd_->err();
  EXPECT_EQ(*code, 0) << rackd_->err();
  EXPECT_TRUE(contains(rackd_->err(), "stopped cleanly")) << rackd_->err();
}

// ------------------------------------------------------------------ failing init

class RackdProbeTest : public IntegrationTest {
 protected:
  // A Generator and a Probe (both autostart) on this test's bus; `probe_extra` ends
  // the probe's entry (e.g. its params).
  std::string probe_host(const std::string& name, const std::string& probe_extra = "") {
    return "host: " + name +
           "\n"
           "system: 0\n"
           "lcm: true\n"
           "lcm_url: \"" +
           bus_.url() +
           "\"\n"
           "heap_prefault_mib: 8\n"
           "components:\n"
           "  - name: generator\n"
           "    class: Generator\n"
           "    instance: 0\n"
           "    autostart: true\n"
           "    data_task: {priority: 60, period_ms: 10}\n"
           "  - name: probe\n"
           "    class: Probe\n"
           "    instance: 0\n"
           "    autostart: true\n"
           "    data_task: {priority: 50, period_ms: 10}\n" +
           probe_extra;
  }
};

TEST_F(RackdProbeTest, FailedInitLeavesTheOtherComponentsRunning) {
  const std::string host = probe_host("probe-host", "    params:\n      fail_init: true\n");
  auto d = start_rackd(dir_.write("probe.yaml", host).string());
  ASSERT_NE(d, nullptr);
  EXPECT_TRUE(contains(d->err(), "fail_init is set")) << d->err();

  EXPECT_EQ(state_of("probe"), "ERROR");
  EXPECT_TRUE(eventually([&] { return state_of("generator") == "ENABLED"; }));
  const RunResult list = ctl({"list"}, "1000");
  ASSERT_EQ(list.exit_code, 0) << list.describe();
  for (const auto& l : lines_of(list.out)) {
    if (contains(l, "Probe(0/0)")) {
      EXPECT_TRUE(contains(l, "ERROR")) << l;
    }
    if (contains(l, "Generator(0/0)")) {
      EXPECT_TRUE(contains(l, "ENABLED")) << l;
    }
  }
  // ON is refused with init()'s reason; the generator stays usable.
  const RunResult on = ctl({"on", "probe"});
  EXPECT_EQ(on.exit_code, 1) << on.describe();
  EXPECT_TRUE(contains(on.err, "fail_init is set")) << on.describe();
  const RunResult data = ctl({"get-data", "generator"});
  EXPECT_EQ(data.exit_code, 0) << data.describe();
  EXPECT_TRUE(parse_json(data.out).has_value()) << data.out;
  EXPECT_EQ(ctl({"set-param", "generator", "amplitude", "3"}).exit_code, 0);
  EXPECT_EQ(state_of("generator"), "ENABLED");

  d->signal(SIGTERM);
  EXPECT_EQ(d->wait_exit(kSettleLimit), std::optional<int>(0)) << d->err();
  EXPECT_TRUE(contains(d->err(), "stopped cleanly")) << d->err();
}

// rackctl send by command name, with the body built from FIELD=VALUE arguments; a
// value that does not fit, an unknown field or command is a usage error that sends
// nothing.
TEST_F(RackdProbeTest, SendByNameBuildsTheBodyFromFields) {
  const std::string host = probe_host("send-host");
  auto d = start_rackd(dir_.write("send.yaml", host).string());
  ASSERT_NE(d, nullptr);
  ASSERT_TRUE(eventually([&] { return state_of("probe") == "ENABLED"; }));

  // ECHO returns its body: value=77 went out as 8 little-endian bytes (x86 host order).
  RunResult r = ctl({"send", "probe", "echo", "value=77"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "OK")) << r.out;
  EXPECT_TRUE(contains(r.out, "body 4d00000000000000")) << r.out;
  EXPECT_TRUE(contains(r.err, "\"value\": 77")) << "the body sent is shown: " << r.err;
  // The same by number and --i64.
  r = ctl({"send", "probe", "21", "--i64", "-2"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "body feffffffffffffff")) << r.out;
  EXPECT_EQ(ctl({"send", "generator", "RESET"}).exit_code, 0);

  const auto usage = [&](std::vector<std::string> args, const std::string& why) {
    const RunResult u = ctl(std::move(args));
    EXPECT_EQ(u.exit_code, 2) << u.describe();
    EXPECT_TRUE(contains(u.err, why)) << u.describe();
  };
  usage({"send", "probe", "ECHO", "value=seven"}, "field 'value': 'seven' is not an integer");
  usage({"send", "probe", "ECHO", "speed=1"}, "no field 'speed' (fields: value)");
  usage({"send", "probe", "ECHO", "value"}, "'value' is not FIELD=VALUE");
  usage({"send", "probe", "ECHO", "value=1", "--i64", "1"}, "either --i64 or FIELD=VALUE");
  usage({"send", "probe", "NOPE"}, "known: ECHO, THROW");
  usage({"send", "generator", "RESET", "x=1"}, "takes no fields");
  usage({"send", "probe", "200"}, "21..127");
  // Nothing of the refused sends reached the probe: it is still ENABLED (THROW would not be).
  EXPECT_EQ(state_of("probe"), "ENABLED");

  d->signal(SIGTERM);
  EXPECT_EQ(d->wait_exit(kSettleLimit), std::optional<int>(0)) << d->err();
}

}  // namespace
}  // namespace rack::test
