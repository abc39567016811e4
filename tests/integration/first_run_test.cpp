// Integration: what a new user meets first (a fresh clone, the README, the example
// host files). Every host file under configs/ passes `rackd --check` and its header
// says what it runs and how to run it; the first mistakes (rackd without a host file,
// a host file that is not there, rackctl with no rackd on the network, rack-gui on a
// port that is taken, rackd without real-time rights) are answered with what is wrong
// and what to do, within a bounded time.
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kGui = RACK_GUI_PATH;
const std::filesystem::path kSource = RACK_SOURCE_DIR;
const std::filesystem::path kConfigs = RACK_CONFIGS_DIR;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Every host file of configs/, as paths relative to the source tree
// ("configs/two_robots/robot1_aux.yaml"); configs/maps/ holds map_server YAML.
std::vector<std::string> shipped_host_files() {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::recursive_directory_iterator(kConfigs)) {
    if (!e.is_regular_file() || e.path().extension() != ".yaml") continue;
    const std::string rel = e.path().lexically_relative(kSource).string();
    if (rel.rfind("configs/maps/", 0) == 0) continue;
    out.push_back(rel);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The comment lines before a host file's first key.
std::vector<std::string> header_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    if (line[0] != '#') break;
    out.push_back(line);
  }
  return out;
}

std::string header_text(const std::string& text) {
  std::string out;
  for (const auto& l : header_of(text)) out += l + "\n";
  return out;
}

class ShippedConfigsTest : public ::testing::Test {
 protected:
  ShippedConfigsTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  Watchdog watchdog_;
  TempDir dir_;
};

// What a shipped host file may need before its first run, that its header tells and
// rackd's refusal names: a log shipped compressed (replay_intel_mcl.yaml), a link key
// made once per robot (access_control.yaml's /etc/rack/robot.key).
struct FirstRunStep {
  const char* refusal;  // in each error line rackd prints
  const char* header;   // in the host file's header
};
constexpr FirstRunStep kFirstRunSteps[] = {
    {".gz is beside it: unpack it with gunzip -k ", "gunzip -k "},
    {"(make one with: rackctl keygen ", "rackctl keygen "},
};

TEST_F(ShippedConfigsTest, EveryHostFileInConfigsPassesRackdCheck) {
  const auto files = shipped_host_files();
  ASSERT_GE(files.size(), 20u) << "the host files of " << kConfigs;
  // Four checks at a time (a check loads the plug-ins the file names: MRPT, PCL, OpenCV).
  constexpr std::size_t kAtOnce = 4;
  for (std::size_t first = 0; first < files.size(); first += kAtOnce) {
    std::vector<std::unique_ptr<Process>> checks;
    const std::size_t end = std::min(files.size(), first + kAtOnce);
    for (std::size_t i = first; i < end; ++i) {
      checks.push_back(
          std::make_unique<Process>(std::vector<std::string>{kRackd, "--check", (kSource / files[i]).string()},
                                    dir_.path(), "check" + std::to_string(i)));
    }
    for (std::size_t i = first; i < end; ++i) {
      Process& p = *checks[i - first];
      const auto code = p.wait_exit(60s);
      const std::string& file = files[i];
      const std::string text = read_file(kSource / file);
      // Refused only for a first-run step this machine has not taken: each error says
      // how, and the file's header says so too.
      const auto errors = lines_of(p.err());
      const auto step_of = [](const std::string& line) -> const FirstRunStep* {
        for (const auto& s : kFirstRunSteps) {
          if (contains(line, s.refusal)) return &s;
        }
        return nullptr;
      };
      if (code == std::optional<int>(2) && errors.size() >= 2 &&
          std::all_of(errors.begin(), errors.end() - 1, [&](const std::string& l) { return step_of(l) != nullptr; })) {
        for (auto e = errors.begin(); e != errors.end() - 1; ++e) {
          EXPECT_TRUE(contains(header_text(text), step_of(*e)->header))
              << file << " is refused for a step its header does not tell: " << *e;
        }
        continue;
      }
      EXPECT_EQ(code, std::optional<int>(0)) << file << ":\n" << p.err();
      EXPECT_TRUE(contains(p.out(), ": valid (")) << file << ": " << p.out();
    }
  }
}

// access_control.yaml with its key made as its header says: valid.
TEST_F(ShippedConfigsTest, AccessControlIsValidOnceItsKeyIsMade) {
  const std::string key = (dir_.path() / "robot.key").string();
  const RunResult made = run({kRackctl, "keygen", key}, 30s);
  ASSERT_EQ(made.exit_code, 0) << made.describe();
  std::string text = read_file(kConfigs / "access_control.yaml");
  const std::string shipped_key = "/etc/rack/robot.key";
  const auto at = text.find("key_file: " + shipped_key);
  ASSERT_NE(at, std::string::npos) << "access_control.yaml names no key_file " << shipped_key;
  text.replace(at + 10, shipped_key.size(), key);
  const auto copy = dir_.write("access_control.yaml", text);
  const RunResult r = run({kRackd, "--check", copy.string()}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

TEST_F(ShippedConfigsTest, EveryHostFileSaysWhatItRunsAndHowToRunIt) {
  for (const auto& file : shipped_host_files()) {
    const auto header = header_of(read_file(kSource / file));
    // What it runs: a paragraph of comments before the first key.
    EXPECT_GE(header.size(), 3u) << file << ": no comment header saying what it runs";
    // How to run it: a rackd command line with the file's path from the repository root.
    const bool run_line = std::any_of(header.begin(), header.end(), [&](const std::string& l) {
      const auto at = l.find("rackd ");
      return at != std::string::npos && l.find(" " + file, at) != std::string::npos;
    });
    EXPECT_TRUE(run_line) << file << ": its header shows no 'rackd ... " << file << "' line";
  }
}

class FirstErrorsTest : public ::testing::Test {
 protected:
  FirstErrorsTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
};

TEST_F(FirstErrorsTest, RackdWithoutAHostFileSaysHowToGiveOne) {
  const RunResult r = run({kRackd}, 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  const auto lines = lines_of(r.err);
  ASSERT_FALSE(lines.empty()) << r.describe();
  // The problem first, then what to do, in a screenful (not the whole --help).
  EXPECT_EQ(lines[0].rfind("rackd: no host file given", 0), 0u) << r.err;
  EXPECT_TRUE(contains(r.err, "rackd configs/demo.yaml")) << r.err;
  EXPECT_TRUE(contains(r.err, "rackd --help")) << r.err;
  EXPECT_LE(lines.size(), 10u) << r.err;
  // An unknown option: named, and where the options are.
  const RunResult u = run({kRackd, "--chek", "x.yaml"}, 30s);
  EXPECT_EQ(u.exit_code, 2) << u.describe();
  EXPECT_TRUE(contains(u.err, "rackd: unknown option '--chek' (rackd --help lists the options)")) << u.err;
  EXPECT_LE(lines_of(u.err).size(), 2u) << u.err;
}

TEST_F(FirstErrorsTest, RackdWithAMissingHostFileNamesIt) {
  const std::string missing = (dir_.path() / "nowhere.yaml").string();
  for (const bool check : {false, true}) {
    std::vector<std::string> args{kRackd, missing, "--lcm", bus_.url()};
    if (check) args.insert(args.begin() + 1, "--check");
    const RunResult r = run(args, 30s);
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    EXPECT_TRUE(contains(r.err, missing)) << r.err;
    EXPECT_TRUE(contains(r.err, "No such file or directory")) << r.err;
    EXPECT_TRUE(contains(r.err, "nothing started")) << r.err;
  }
  // A relative name: where it was looked for (the usual miss: run from another folder).
  const RunResult rel = run({"/bin/sh", "-c", "cd \"$1\" && exec \"$0\" nowhere.yaml", kRackd, dir_.path().string()},
                            30s);
  EXPECT_EQ(rel.exit_code, 2) << rel.describe();
  EXPECT_TRUE(contains(rel.err,
                       "nowhere.yaml: cannot read the host file: No such file or directory (looked for from "
                       "the working directory " +
                           std::filesystem::canonical(dir_.path()).string() + ")"))
      << rel.err;
}

TEST_F(FirstErrorsTest, RackctlWithNoRackdSaysNoneAnsweredAndWhatToDo) {
  for (const char* command : {"list", "hosts", "classes"}) {
    // Bounded: the 300 ms of discovery and start-up; a hang is killed at 15 s (a bound
    // for a loaded machine, not a timing figure).
    const RunResult r = run({kRackctl, "--lcm", bus_.url(), command}, 15s);
    EXPECT_FALSE(r.timed_out) << command;
    EXPECT_EQ(r.exit_code, 3) << command << ": " << r.describe();
    EXPECT_TRUE(contains(r.err, "answered discovery within 300 ms on udpm://")) << command << ": " << r.err;
    EXPECT_TRUE(contains(r.err, "is a rackd running on this network?")) << command << ": " << r.err;
    EXPECT_TRUE(contains(r.err, "--lcm URL")) << command << ": " << r.err;
  }
  const RunResult r = run({kRackctl, "--lcm", bus_.url(), "status", "generator"}, 30s);
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "no component named 'generator' answered discovery")) << r.err;
  EXPECT_TRUE(contains(r.err, "rackctl list shows the components that answer")) << r.err;
}

// rackctl --help lists every command with the options its own help gives (a new user
// reads the first and never learns of --json on list, or --host on trace).
TEST_F(FirstErrorsTest, RackctlHelpShowsEachCommandAsItsOwnHelpDoes) {
  const RunResult help = run({kRackctl, "--help"}, 30s);
  ASSERT_EQ(help.exit_code, 0) << help.describe();
  const auto commands_at = help.out.find("\ncommands:\n");
  const auto commands_end = help.out.find("\n\n", commands_at + 1);
  ASSERT_NE(commands_at, std::string::npos) << help.out;
  const std::string listing = help.out.substr(commands_at, commands_end - commands_at);
  std::size_t checked = 0;
  for (const auto& line : lines_of(listing)) {
    // "  NAME ..." starts a command; deeper indents continue its description.
    if (line.size() < 3 || line[0] != ' ' || line[1] != ' ' || line[2] == ' ') continue;
    const std::string command = line.substr(2, line.find(' ', 2) - 2);
    const RunResult own = run({kRackctl, "help", command}, 30s);
    ASSERT_EQ(own.exit_code, 0) << command << ": " << own.describe();
    const std::string prefix = "usage: rackctl [options] ";
    ASSERT_EQ(own.out.rfind(prefix, 0), 0u) << own.out;
    const std::string synopsis = own.out.substr(prefix.size(), own.out.find('\n') - prefix.size());
    EXPECT_TRUE(contains(listing, "\n  " + synopsis + " ") || contains(listing, "\n  " + synopsis + "\n"))
        << "rackctl --help shows '" << command << "' otherwise than its own help: " << synopsis;
    ++checked;
  }
  EXPECT_GE(checked, 20u) << listing;
}

// A typo in a simulator's option ran the device with the default, saying nothing.
TEST_F(FirstErrorsTest, RackDevsimRefusesAnOptionItsDeviceDoesNotTake) {
  const std::string link = (dir_.path() / "gps0").string();
  RunResult r = run({RACK_DEVSIM_PATH, "gps", "--link", link, "--rat", "10", "--duration", "0.1"}, 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "rack-devsim gps: unknown option '--rat' (rack-devsim --help lists each device's)"))
      << r.err;
  // An option of another device is not one of this one's.
  r = run({RACK_DEVSIM_PATH, "sick", "--nodes", "1,2", "--duration", "0.1"}, 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "unknown option '--nodes'")) << r.err;
  // A stick repeated without pause spun a core.
  r = run({RACK_DEVSIM_PATH, "joystick", "--fifo", (dir_.path() / "js0").string(), "--period-ms", "0"}, 30s);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "--period-ms must be in 1..60000")) << r.err;
  // Its own options still run it.
  r = run({RACK_DEVSIM_PATH, "gps", "--link", link, "--rate", "10", "--duration", "0.2"}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

TEST_F(FirstErrorsTest, RackGuiOnAPortInUseSaysSoAndWhatToDo) {
  // A port held by someone else: bound and listening on 127.0.0.1.
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = 0;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(fd, 4), 0);
  socklen_t len = sizeof a;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len), 0);
  const std::string port = std::to_string(ntohs(a.sin_port));
  // A front end of its own, so that this does not depend on tools/gui/web being built.
  const auto web = dir_.path() / "web";
  std::filesystem::create_directories(web);
  dir_.write("web/index.html", "<!doctype html><title>t</title>\n");
  const RunResult r = run({kGui, "--lcm", bus_.url(), "--port", port, "--web", web.string()}, 30s);
  ::close(fd);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "rack-gui: cannot listen on 127.0.0.1:" + port + ": Address already in use")) << r.err;
  EXPECT_TRUE(contains(r.err, "--port PORT for another, --port 0 for any free one")) << r.err;
}

TEST_F(FirstErrorsTest, RackdWithoutRealTimeRightsSaysWhatToDoAndRuns) {
  // A user's login: no capabilities, no rtprio, Debian's 8 MiB memlock limit.
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to start rackd as nobody (setpriv)";
  const auto setpriv = find_program("setpriv");
  const auto prlimit = find_program("prlimit");
  if (!setpriv || !prlimit) GTEST_SKIP() << "setpriv and prlimit (util-linux) are not installed";
  std::filesystem::permissions(dir_.path(), std::filesystem::perms::all);  // the crash dir, for nobody
  const RunResult r = run({*prlimit, "--rtprio=0", "--memlock=8388608", "--", *setpriv, "--reuid=65534",
                           "--regid=65534", "--clear-groups", "--inh-caps=-all", "--bounding-set=-all", kRackd,
                           (kConfigs / "demo.yaml").string(), "--lcm", bus_.url(), "--duration", "1", "--crash-dir",
                           dir_.path().string()},
                          60s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.err, "rackd: WARNING: no real-time rights (SCHED_FIFO refused")) << r.err;
  EXPECT_TRUE(contains(r.err, "/etc/security/limits.conf")) << r.err;
  EXPECT_TRUE(contains(r.err, "`rackctl doctor` checks this machine")) << r.err;
  EXPECT_TRUE(contains(r.err, "rackd: stopped cleanly")) << r.err;
}

}  // namespace
}  // namespace rack::test
