// Integration: the command-line conventions every tool keeps (issue 21, item 6):
// --version everywhere, rackctl hz / bw against a real rackd on a private bus,
// rackctl doctor on this machine, and the bash completion script against each
// tool's own --help.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <regex>
#include <set>
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
const std::string kCompletion = std::string(RACK_SOURCE_DIR) + "/tools/completion/rack.bash";

struct Tool {
  const char* name;
  std::string path;
};
const std::vector<Tool>& tools() {
  static const std::vector<Tool> kTools = {
      {"rackd", RACK_RACKD_PATH},  {"rackctl", RACK_RACKCTL_PATH},          {"gdos", RACK_GDOS_PATH},
      {"rack-gui", RACK_GUI_PATH}, {"rack-backtrace", RACK_BACKTRACE_PATH}, {"rack-devsim", RACK_DEVSIM_PATH}};
  return kTools;
}

// Every --long-option a text mentions.
std::set<std::string> long_options(const std::string& text) {
  std::set<std::string> out;
  const std::regex re("(^|[\\s,\\[])(--[a-z][a-z0-9-]*)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it) {
    out.insert((*it)[2].str());
  }
  return out;
}

class CliTest : public ::testing::Test {
 protected:
  CliTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void TearDown() override {
    if (rackd_ && rackd_->running()) {
      rackd_->signal(SIGTERM);
      EXPECT_EQ(rackd_->wait_exit(30s), std::optional<int>(0)) << rackd_->err();
    }
  }
  RunResult ctl(std::vector<std::string> args) {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url(), "--discover-ms", "3000"});
    return run(args, 30s);
  }
  void start_demo() {
    rackd_ = std::make_unique<Process>(std::vector<std::string>{kRackd, kConfigs + "/demo.yaml", "--lcm", bus_.url()},
                                       dir_.path(), "rackd");
    ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
    // The monitor switches the generator on (cascading ON) at autostart.
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    while (std::chrono::steady_clock::now() < deadline) {
      const RunResult r = ctl({"status", "generator", "--json"});
      if (r.exit_code == 0 && r.out.find("\"state\":\"ENABLED\"") != std::string::npos) return;
      std::this_thread::sleep_for(100ms);
    }
    FAIL() << "the generator did not come up ENABLED";
  }
  // The candidates the completion script offers for the words `line` (the last one
  // being completed), as bash would call it.
  std::set<std::string> complete(const std::string& line) {
    std::istringstream in(line);
    std::vector<std::string> words;
    for (std::string w; in >> w;) words.push_back(w);
    if (!line.empty() && line.back() == ' ') words.emplace_back();
    std::string array;
    for (const auto& w : words) array += " '" + w + "'";
    // The tools on PATH, as after the README's export; COMP_LINE/COMP_POINT as bash sets them.
    const std::string path = std::filesystem::path(kRackctl).parent_path().string() + ":" +
                             std::filesystem::path(RACK_GUI_PATH).parent_path().string() + ":/usr/bin:/bin";
    const std::string script = "export PATH='" + path + "'; source '" + kCompletion + "'; COMP_WORDS=(" + array +
                               "); COMP_CWORD=" + std::to_string(words.size() - 1) + "; COMP_LINE='" + line +
                               "'; COMP_POINT=" + std::to_string(line.size()) + "; fn=$(complete -p " + words[0] +
                               " | sed 's/.*-F \\([^ ]*\\).*/\\1/'); $fn; printf '%s\\n' \"${COMPREPLY[@]}\"";
    const RunResult r = run({"/bin/bash", "-c", script}, 30s);
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    std::set<std::string> out;
    for (const auto& l : lines_of(r.out)) out.insert(l);
    return out;
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::unique_ptr<Process> rackd_;
};

TEST_F(CliTest, EveryToolPrintsItsVersion) {
  for (const auto& t : tools()) {
    const RunResult r = run({t.path, "--version"}, 30s);
    EXPECT_EQ(r.exit_code, 0) << t.name << ": " << r.describe();
    // "NAME MAJOR.MINOR.PATCH" and, in a git checkout, " (git DESCRIBE)".
    EXPECT_TRUE(
        std::regex_match(r.out, std::regex(std::string(t.name) + " [0-9]+\\.[0-9]+\\.[0-9]+( \\(git [^)]+\\))?\n")))
        << t.name << ": " << r.describe();
    const RunResult help = run({t.path, "--help"}, 30s);
    EXPECT_NE(help.out.find("--version"), std::string::npos) << t.name << " --help does not mention --version";
  }
}

TEST_F(CliTest, HzAndBwMeasureTheGeneratorsStream) {
  start_demo();
  // --json: one object per report, a report a second; --count 2 ends after two.
  RunResult r = ctl({"hz", "generator", "--count", "2", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  auto lines = lines_of(r.out);
  ASSERT_EQ(lines.size(), 2u) << r.describe();
  const auto j = parse_json(lines[1]);
  ASSERT_TRUE(j) << lines[1];
  EXPECT_GE(j->at("samples").number, 2.0) << lines[1];
  EXPECT_GT(j->at("rate_hz").number, 0.0) << lines[1];
  const Json& period = j->at("period_s");
  EXPECT_LE(period.at("min").number, period.at("mean").number) << lines[1];
  EXPECT_LE(period.at("mean").number, period.at("max").number) << lines[1];
  EXPECT_GE(period.at("std").number, 0.0) << lines[1];
  // The rate is the inverse of the mean period.
  EXPECT_NEAR(j->at("rate_hz").number * period.at("mean").number, 1.0, 1e-3) << lines[1];

  r = ctl({"bw", "generator", "--count", "1", "--window", "10", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto b = parse_json(r.out);
  ASSERT_TRUE(b) << r.describe();
  EXPECT_LE(b->at("samples").number, 10.0);
  EXPECT_GT(b->at("bytes_per_s").number, 0.0) << r.out;
  // Every generator sample is the same size: a TiMS header, a sample header, the data.
  EXPECT_EQ(b->at("size_bytes").at("min").number, b->at("size_bytes").at("max").number) << r.out;

  // Text: units on every number.
  r = ctl({"hz", "generator", "--count", "1"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(std::regex_search(
      r.out, std::regex("^rate [0-9.]+ k?Hz  period min [0-9.]+ [mun]?s, max .* std .*\\(window [0-9]+ samples\\)")))
      << r.out;
}

TEST_F(CliTest, HzRefusesBadOptionsAndUnknownNames) {
  EXPECT_EQ(ctl({"hz", "generator", "--window", "1"}).exit_code, 2);
  EXPECT_EQ(ctl({"bw"}).exit_code, 2);
  EXPECT_EQ(ctl({"hz", "generator", "--time", "5"}).exit_code, 2);  // not an option of hz
  const RunResult r = run({kRackctl, "--lcm", bus_.url(), "--discover-ms", "300", "hz", "nobody"}, 30s);
  EXPECT_EQ(r.exit_code, 3) << r.describe();
}

TEST_F(CliTest, DoctorChecksThisMachineAndSaysTheFix) {
  RunResult r = run({kRackctl, "doctor", "--json"}, 30s);
  ASSERT_TRUE(r.exit_code == 0 || r.exit_code == 1) << r.describe();
  const auto j = parse_json(r.out);
  ASSERT_TRUE(j && j->type == Json::Type::kArray) << r.describe();
  std::set<std::string> names;
  bool failed = false;
  for (const auto& c : j->array) {
    names.insert(c.at("check").string);
    const std::string verdict = c.at("verdict").string;
    EXPECT_TRUE(verdict == "ok" || verdict == "WARN" || verdict == "FAIL") << verdict;
    EXPECT_EQ(verdict == "ok", c.at("fix").string.empty()) << c.at("check").string << ": a problem needs a fix";
    failed = failed || verdict == "FAIL";
  }
  EXPECT_EQ(r.exit_code, failed ? 1 : 0) << r.describe();
  EXPECT_EQ(names, (std::set<std::string>{"rt-priority", "memlock", "multicast-route", "rmem-max", "preempt-rt",
                                          "cpu-dma-latency", "clocksource"}));
  r = run({kRackctl, "doctor"}, 30s);
  EXPECT_EQ(lines_of(r.out).size() >= 7u, true) << r.describe();
  EXPECT_TRUE(std::regex_search(r.out, std::regex("(^|\n)(ok  |WARN|FAIL) rt-priority "))) << r.out;
}

TEST_F(CliTest, CompletionOffersEveryOptionOfEachToolsHelp) {
  if (run({"/bin/bash", "-c", "true"}, 30s).exit_code != 0) GTEST_SKIP() << "no /bin/bash";
  for (const auto& t : tools()) {
    std::set<std::string> offered;
    if (std::string(t.name) == "rack-devsim") {
      for (const char* dev : {"gps", "cia402", "hokuyo", "sick", "joystick"}) {
        const auto c = complete(std::string("rack-devsim ") + dev + " --");
        offered.insert(c.begin(), c.end());
      }
      const auto first = complete("rack-devsim --");
      offered.insert(first.begin(), first.end());
    } else if (std::string(t.name) == "rackctl") {
      for (const char* cmd :
           {"list", "status", "get-data", "watch", "send", "hz", "doctor", "classes", "trace", "graph", "alloc"}) {
        const auto c = complete(std::string("rackctl ") + cmd + " --");
        offered.insert(c.begin(), c.end());
      }
    } else {
      offered = complete(std::string(t.name) + " --");
    }
    std::string help = run({t.path, "--help"}, 30s).out;
    if (std::string(t.name) == "rackctl") {
      for (const char* cmd :
           {"list", "status", "get-data", "watch", "send", "hz", "doctor", "classes", "trace", "graph", "alloc"}) {
        help += run({t.path, "help", cmd}, 30s).out;
      }
    }
    for (const auto& opt : long_options(help)) {
      EXPECT_EQ(offered.count(opt), 1u) << t.name << ": completion does not offer " << opt;
    }
    for (const auto& opt : offered) {
      EXPECT_TRUE(help.find(opt) != std::string::npos)
          << t.name << ": completion offers " << opt << ", which --help does not mention";
    }
  }
}

// rack-foxglove (tools/foxglove, node): its completion against its --help, the
// bridge's options and play's.
TEST_F(CliTest, CompletionOffersEveryOptionOfRackFoxglovesHelp) {
  if (run({"/bin/bash", "-c", "true"}, 30s).exit_code != 0) GTEST_SKIP() << "no /bin/bash";
  const auto node = find_program("node");
  if (!node) GTEST_SKIP() << "node is not installed (Debian: apt-get install nodejs); scripts/setup.sh installs it";
  const std::string script = std::string(RACK_SOURCE_DIR) + "/tools/foxglove/rack-foxglove.mjs";
  const RunResult help = run({*node, script, "--help"}, 30s);
  ASSERT_EQ(help.exit_code, 0) << help.describe() << " (npm ci in tools/foxglove: scripts/setup.sh)";
  std::set<std::string> offered = complete("rack-foxglove --");
  const auto play = complete("rack-foxglove play rec.mcap --");
  offered.insert(play.begin(), play.end());
  EXPECT_EQ(complete("rack-foxglove pl"), (std::set<std::string>{"play"}));
  EXPECT_EQ(complete("rack-foxglove --compression l"), (std::set<std::string>{"lz4"}));
  const auto options = long_options(help.out);
  EXPECT_GE(options.size(), 15u) << help.out;
  for (const auto& opt : options) EXPECT_EQ(offered.count(opt), 1u) << "completion does not offer " << opt;
  for (const auto& opt : offered) {
    EXPECT_NE(help.out.find(opt), std::string::npos)
        << "completion offers " << opt << ", which --help does not mention";
  }
}

TEST_F(CliTest, CompletionOfRackctlCommandsAndNames) {
  EXPECT_EQ(complete("rackctl h"), (std::set<std::string>{"hosts", "help", "hz"}));
  EXPECT_EQ(complete("rackctl help st"), (std::set<std::string>{"status"}));
  start_demo();
  // Names come from a discovery on the bus given on the command line.
  EXPECT_EQ(complete("rackctl --lcm " + bus_.url() + " status gen"), (std::set<std::string>{"generator"}));
  EXPECT_EQ(complete("rackctl --lcm " + bus_.url() + " hz m"), (std::set<std::string>{"monitor"}));
}

}  // namespace
}  // namespace rack::test
