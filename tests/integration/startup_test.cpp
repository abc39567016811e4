// Start-up is strict and stoppable (issue 17): the real rackd binary.
//
//   - a corpus of malformed host files, one per rule, written here at run time: each
//     is refused by `rackd --check` with file:line:col, the rule's message and exit 2;
//   - every "cannot start" path says what and where and exits 1, never aborts (no
//     exit 134, no crash report);
//   - SIGINT/SIGTERM end rackd within a second at any point of its start-up: between
//     start-up steps (undone in order) and inside one that does not return (a slow
//     init(): the Probe's init_delay_ms).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;
const std::string kUnshare = "/usr/bin/unshare";  // util-linux

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class StartupTest : public ::testing::Test {
 protected:
  StartupTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  RunResult rackd(std::vector<std::string> args) {
    args.insert(args.begin(), kRackd);
    return run(args, 30s);
  }
  // A crash report with content in the crash directory (rackd removes empty ones).
  bool crash_reported() {
    if (!std::filesystem::exists(crash_dir_)) return false;
    for (const auto& e : std::filesystem::directory_iterator(crash_dir_)) {
      if (e.is_regular_file() && e.file_size() > 0) return true;
    }
    return false;
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::string crash_dir_ = (dir_.path() / "crash").string();
};

// ---------------------------------------------------------------- --check corpus

const std::string kComponent = R"(components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
)";

struct Malformed {
  const char* name;
  std::string text;
  int line;             // where the error must be reported (0: the whole file)
  const char* message;  // part of the message
};

std::vector<Malformed> corpus() {
  const std::string lcm_off = "lcm: false\n";
  return {
      {"duplicate_top_level_key", "system: 0\nsystem: 1\n" + kComponent, 2, "duplicate key 'system' (first at line 1)"},
      {"duplicate_param", lcm_off + kComponent + "    params:\n      amplitude: 1\n      amplitude: 2\n", 8,
       "duplicate key 'amplitude' (first at line 7)"},
      {"duplicate_task_key",
       lcm_off + "components:\n  - name: gen\n    class: Generator\n    data_task:\n      period_ms: 10\n"
                 "      period_ms: 20\n",
       7, "duplicate key 'period_ms'"},
      {"duplicate_component_key",
       lcm_off + "components:\n  - name: gen\n    name: gen2\n    class: Generator\n"
                 "    data_task: {period_ms: 10}\n",
       4, "duplicate key 'name'"},
      {"cpu_wraps",
       lcm_off + "components:\n  - name: gen\n    class: Generator\n"
                 "    data_task: {period_ms: 10, cpu: 4294967297}\n",
       5, "CPU 4294967297 is not online"},
      {"priority_overflows",
       lcm_off + "components:\n  - name: gen\n    class: Generator\n"
                 "    data_task: {period_ms: 10, priority: 18446744073709551617}\n",
       5, "'priority' must be"},
      {"system_out_of_range", "system: 255\n" + kComponent, 1, "'system' = 255 is outside 0..254"},
      {"instance_out_of_range",
       lcm_off + "components:\n  - name: gen\n    class: Generator\n    instance: 256\n"
                 "    data_task: {period_ms: 10}\n",
       5, "'instance' = 256 is outside 0..255"},
      {"period_beyond_a_day",
       lcm_off + "components:\n  - name: gen\n    class: Generator\n"
                 "    data_task: {period_ms: 1e300}\n",
       5, "above 86400000 ms"},
      {"garbage_lcm_url", "lcm_url: garbage\n" + kComponent, 1, "is not an LCM URL"},
      {"lcm_url_bad_port", "lcm_url: \"udpm://239.255.76.67:76670?ttl=0\"\n" + kComponent, 1, "not a number 1..65535"},
      {"lcm_url_not_multicast", "lcm_url: \"udpm://192.168.1.1:7667\"\n" + kComponent, 1, "not a multicast address"},
      {"lcm_url_unknown_option", "lcm_url: \"udpm://239.255.76.67:7667?tl=0\"\n" + kComponent, 1,
       "unknown option 'tl'"},
      {"gdos_lcm_url", "gdos:\n  lcm_url: \"udpm://239.255.76.67:7667?ttl=x\"\n" + kComponent, 2, "ttl 'x'"},
      {"network_url", "tims:\n  networks:\n    - {name: robot, url: \"tcp://robot\"}\n" + kComponent, 3,
       "unknown LCM provider 'tcp'"},
      {"second_document", lcm_off + kComponent + "---\nlcm: true\n", 6, "a second YAML document"},
      {"broken_second_document", lcm_off + kComponent + "---\n{[ not yaml\n", 8, "after the host file's document"},
      {"announce_over_expiry", "tims:\n  announce_ms: 5000\n" + kComponent, 2, "at least twice 'announce_ms'"},
      {"announce_close_to_expiry", "tims:\n  announce_ms: 1000\n  expiry_ms: 1200\n" + kComponent, 3,
       "'expiry_ms' (1200 ms) must be at least twice"},
      {"host_name_100k", "host: " + std::string(100000, 'h') + "\n" + kComponent, 1, "at most 4096 bytes"},
      {"host_name_too_long", "host: " + std::string(64, 'h') + "\n" + kComponent, 1, "host name"},
      {"host_name_control", "host: \"robot\\e[2J\"\n" + kComponent, 1, "control character (U+001B)"},
      {"host_name_escaped_nul", "host: \"ro\\0bot\"\n" + kComponent, 1, "a NUL byte"},
      {"raw_nul_byte", "lcm: false\nhost: ro" + std::string(1, '\0') + "bot\n" + kComponent, 2, "a NUL byte"},
      {"invalid_utf8_name",
       lcm_off + "components:\n  - name: g\xe9n\n    class: Generator\n"
                 "    data_task: {period_ms: 10}\n",
       3, "invalid UTF-8"},
      {"component_name_spaces",
       lcm_off + "components:\n  - name: \"my gen\"\n    class: Generator\n"
                 "    data_task: {period_ms: 10}\n",
       3, "component name"},
      {"control_in_param",
       lcm_off + "components:\n  - name: p\n    class: Probe\n    data_task: {period_ms: 10}\n"
                 "    params: {label: \"a\\x07b\"}\n",
       6, "control character (U+0007)"},
      {"nested_too_deep", lcm_off + "x: " + std::string(40, '[') + std::string(40, ']') + "\n" + kComponent, 2,
       "nested deeper than 32"},
      {"pilot_mode",
       lcm_off + "components:\n  - name: pilot\n    class: Pilot\n    data_task: {period_ms: 50}\n"
                 "    params:\n      chassis: \"Chassis(0/9)\"\n      position: \"Position(0/9)\"\n"
                 "      scan2d: \"Scan2D(0/9)\"\n      mode: fly\n",
       10, "must be one of path, hold, got 'fly'"},
      {"path_waypoints",
       lcm_off + "components:\n  - name: path\n    class: Path\n    data_task: {period_ms: 200}\n"
                 "    params: {waypoints: \"0,0; 1\"}\n",
       6, "parameter 'waypoints': item 2"},
      {"too_large", std::string((1u << 20) + 1, '#'), 0, "bytes: at most 1048576 are read"},
  };
}

// One test per rule (ctest runs them apart): the file is written here, rackd --check
// must refuse it with exit 2 and the rule's message at file:line:col.
class CheckCorpusTest : public StartupTest, public ::testing::WithParamInterface<Malformed> {};

TEST_P(CheckCorpusTest, RackdCheckRefusesItWithFileLineAndColumn) {
  const Malformed& m = GetParam();
  const auto path = dir_.write(std::string(m.name) + ".yaml", m.text);
  const RunResult r = rackd({"--check", path.string()});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  const std::string where = m.line > 0 ? path.string() + ":" + std::to_string(m.line) + ":" : path.string() + ": ";
  bool found = false;
  for (std::size_t at = 0; (at = r.err.find(where, at)) != std::string::npos;) {
    const std::size_t end = r.err.find('\n', at);
    if (contains(r.err.substr(at, end - at), m.message)) found = true;
    at = end;
  }
  EXPECT_TRUE(found) << "expected '" << where << "...: " << m.message << "' in:\n" << r.err;
  EXPECT_FALSE(contains(r.err, "CRASH")) << r.err;
}

INSTANTIATE_TEST_SUITE_P(EveryRule, CheckCorpusTest, ::testing::ValuesIn(corpus()),
                         [](const ::testing::TestParamInfo<Malformed>& rule) { return std::string(rule.param.name); });

TEST_F(StartupTest, CheckRefusesFifosAndDevicesWithoutReadingThem) {
  const std::string fifo = (dir_.path() / "host.yaml").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  RunResult r = rackd({"--check", fifo});  // would block in open() or read() if it were read
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, fifo + ": the host file is a FIFO")) << r.describe();
  r = rackd({"--check", "/dev/zero"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "/dev/zero: the host file is a device")) << r.describe();
}

// ---------------------------------------------------------------- cannot start

TEST_F(StartupTest, GarbageLcmOptionIsAUsageErrorNotACrash) {
  const RunResult r = rackd({kConfigs + "/demo.yaml", "--lcm", "garbage", "--crash-dir", crash_dir_});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "rackd: --lcm: 'garbage' is not an LCM URL")) << r.describe();
  EXPECT_FALSE(crash_reported());
}

TEST_F(StartupTest, UnjoinableNetworkExits1WithAMessageAndNoCrashReport) {
  // A network namespace of its own without lo up: LCM cannot create its socket. That
  // was an abort (exit 134) with a false crash report: the mode-switch detector's
  // thread was left running when main returned.
  const RunResult probe = run({kUnshare, "-n", "/bin/true"}, 10s);
  if (probe.exit_code != 0) GTEST_SKIP() << "unshare -n is not permitted here: " << probe.describe();
  const RunResult r = run({kUnshare, "-n", kRackd, kConfigs + "/demo.yaml", "--crash-dir", crash_dir_}, 30s);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "rackd: cannot start: cannot join the LCM network")) << r.describe();
  EXPECT_FALSE(contains(r.err, "CRASH")) << r.describe();
  EXPECT_FALSE(crash_reported());
}

TEST_F(StartupTest, RequiredRealTimeMissingExits1WithWhatIsMissing) {
  const auto host = dir_.write("rt.yaml", "require_rt: true\nlcm: false\nheap_prefault_mib: 0\n" + kComponent);
  const RunResult r = rackd({host.string(), "--duration", "0", "--crash-dir", crash_dir_});
  if (r.exit_code == 0) GTEST_SKIP() << "this machine has every real-time feature: " << r.err;
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "demands real time (require_rt: true) but this host lacks")) << r.describe();
  EXPECT_FALSE(crash_reported());
}

// ---------------------------------------------------------------- stoppable

std::string slow_host(int components, int init_delay_ms) {
  std::string text = "lcm: false\nheap_prefault_mib: 0\ncomponents:\n";
  for (int i = 0; i < components; ++i) {
    text += "  - name: slow" + std::to_string(i) + "\n    class: Probe\n    instance: " + std::to_string(i) +
            "\n    data_task: {period_ms: 100}\n    params: {init_delay_ms: " + std::to_string(init_delay_ms) + "}\n";
  }
  return text;
}

// Sends `sig` once rackd is inside the first component's init() and returns how
// long rackd took to end after it.
std::chrono::milliseconds stop_during_init(Process& p, int sig) {
  EXPECT_TRUE(p.wait_for_stderr("access control", 20s)) << p.err();  // logged just before the init()s
  std::this_thread::sleep_for(100ms);
  const auto t0 = std::chrono::steady_clock::now();
  p.signal(sig);
  const auto code = p.wait_exit(10s);
  const auto took = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - t0);
  EXPECT_TRUE(code.has_value());
  EXPECT_EQ(code.value_or(-2), 1) << p.err();
  return took;
}

TEST_F(StartupTest, SigtermInsideAnInitThatDoesNotReturnEndsRackdWithinASecond) {
  const auto host = dir_.write("slow.yaml", slow_host(1, 60000));
  Process p({kRackd, host.string(), "--crash-dir", crash_dir_}, dir_.path(), "rackd");
  const auto took = stop_during_init(p, SIGTERM);
  EXPECT_LT(took, 1000ms) << p.err();
  EXPECT_TRUE(contains(p.err(), "rackd: Terminated during start-up (init() of component 'slow0'): stopping"))
      << p.err();
  EXPECT_TRUE(contains(p.err(), "start-up did not stop within 500 ms (still init() of component 'slow0')")) << p.err();
  EXPECT_FALSE(contains(p.err(), "CRASH")) << p.err();
}

TEST_F(StartupTest, SigintBetweenStartUpStepsStopsCleanlyWithinASecond) {
  // Three init()s of 300 ms: the signal comes during the first, start-up stops before
  // the second and undoes what it started.
  const auto host = dir_.write("slow.yaml", slow_host(3, 300));
  Process p({kRackd, host.string(), "--crash-dir", crash_dir_}, dir_.path(), "rackd");
  const auto took = stop_during_init(p, SIGINT);
  EXPECT_LT(took, 1000ms) << p.err();
  EXPECT_TRUE(contains(p.err(), "rackd: Interrupt during start-up (init() of component 'slow0'): stopping")) << p.err();
  EXPECT_TRUE(contains(p.err(), "rackd: stopped during start-up by Interrupt; nothing runs (exit 1)")) << p.err();
  EXPECT_FALSE(contains(p.err(), "init() of component 'slow2'")) << p.err();
  EXPECT_FALSE(contains(p.err(), "CRASH")) << p.err();
  EXPECT_FALSE(crash_reported());
}

}  // namespace
}  // namespace rack::test
