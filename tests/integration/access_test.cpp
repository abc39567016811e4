// Integration: access control and authenticated links with the real rackd and rackctl
// over real LCM: an unauthorised MOVE to the simulated chassis, key files (refused
// when others can read them), tools and hosts without the key (same machine and
// another network namespace), a capture replayed with lcm-logplayer, a key rotation.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "netns.h"
#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kGdos = RACK_GDOS_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string find_tool(const std::string& name) {
  for (const char* dir : {"/usr/bin/", "/usr/local/bin/", "/bin/"}) {
    const std::string p = dir + name;
    if (::access(p.c_str(), X_OK) == 0) return p;
  }
  return "";
}

std::string key_line(char fill) { return std::string(64, fill) + "\n"; }

// A generator on a keyed network (the key file's path, and `extra` tims keys).
std::string keyed_host(const std::string& url, const std::string& key_file, const std::string& extra = "") {
  return "host: keyed\nsystem: 0\nhost_id: 0\nheap_prefault_mib: 0\ntims:\n  announce_ms: 300\n  expiry_ms: 1500\n" +
         extra + "  networks:\n    - {name: robot, url: \"" + url + "\", scope: robot, key_file: \"" + key_file +
         "\"}\n" + R"(components:
  - name: generator
    class: Generator
    instance: 0
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 60, period_ms: 10}
    params: {amplitude: 2.0}
)";
}

class AccessTest : public ::testing::Test {
 protected:
  AccessTest() : watchdog_(110s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void TearDown() override {
    if (rackd_ && rackd_->running()) stop();
  }
  // Writes a key file with mode 0600 (atomically: a rename, as an operator would).
  std::string key_file(const std::string& name, const std::string& text, mode_t mode = 0600) {
    const auto tmp = dir_.write(name + ".tmp", text);
    chmod(tmp.c_str(), mode);
    const auto path = dir_.path() / name;
    std::filesystem::rename(tmp, path);
    return path.string();
  }
  void start(const std::string& host_text, const std::vector<std::string>& extra = {}) {
    const auto path = dir_.write("host" + std::to_string(starts_) + ".yaml", host_text);
    std::vector<std::string> args{kRackd, path.string()};
    args.insert(args.end(), extra.begin(), extra.end());
    rackd_ = std::make_unique<Process>(args, dir_.path(), "rackd" + std::to_string(starts_++));
    ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  }
  // Stops rackd (its final status is on stdout).
  void stop() {
    rackd_->signal(SIGTERM);
    EXPECT_EQ(rackd_->wait_exit(30s), std::optional<int>(0)) << rackd_->err();
  }
  RunResult ctl(const std::string& key, std::vector<std::string> args, const std::string& timeout_ms = "2000") {
    std::vector<std::string> head{kRackctl,   "--lcm",     url_, "--discover-ms", "3000", "--timeout",
                                  timeout_ms, "--retries", "1"};
    if (!key.empty()) head.insert(head.end(), {"--key-file", key});
    args.insert(args.begin(), head.begin(), head.end());
    return run(args, 30s);
  }
  double param(const std::string& key, const std::string& name) {
    const RunResult r = ctl(key, {"params", "Generator(0/0)", "--json"});
    if (r.exit_code != 0) return -1e9;
    const auto at = r.out.find("\"name\":\"" + name + "\"");
    if (at == std::string::npos) return -1e9;
    const auto v = r.out.find("\"value\":", at);
    return std::strtod(r.out.c_str() + v + 8, nullptr);
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::string url_ = bus_.url();
  std::unique_ptr<Process> rackd_;
  int starts_ = 0;
};

// configs/sim_nav.yaml (maps made absolute) with an access section: MOVE to the
// chassis only from `driver`; everyone else may switch, read and set it up.
std::string sim_nav_with_access(const std::string& driver) {
  std::string text = read_file(kConfigs + "/sim_nav.yaml");
  const std::string rel = "map: maps/office.yaml";
  for (auto at = text.find(rel); at != std::string::npos; at = text.find(rel, at + 1)) {
    text.replace(at, rel.size(), "map: " + kConfigs + "/maps/office.yaml");
  }
  return text + R"(
access:
  default: open
  log_ms: 500
  rules:
    - name: chassis-drive
      to: chassis
      from: [")" +
         driver + R"("]
    - name: chassis-others
      to: chassis
      types: [on, off, get_status, get_data, get_cont_data, stop_cont_data, get_next_data, get_param,
              set_param, get_stats, get_class, 22, 23]
)";
}

TEST_F(AccessTest, UnauthorisedPilotsMoveToTheChassisIsRefusedAndCounted) {
  // Only a joystick may drive: the pilot's MOVE is refused (answered ERROR), so the
  // pilot stands (PREEMPTED, as when another pilot has the chassis); the robot stays put.
  start(sim_nav_with_access("Joystick(0/*)"), {"--lcm", url_});
  RunResult r;
  ASSERT_TRUE(eventually([&] {
    r = ctl("", {"status", "chassis", "--json"});
    const auto j = parse_json(r.out);
    const Json* d = j ? j->get("access_denied") : nullptr;
    return d != nullptr && d->is_number() && d->number >= 1;
  })) << r.describe();
  r = ctl("", {"get-data", "pilot"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto pilot = parse_json(r.out);
  ASSERT_TRUE(pilot) << r.out;
  EXPECT_GE(pilot->at("data").at("moves_refused").number, 1) << r.out;
  r = ctl("", {"get-data", "chassis"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const auto j = parse_json(r.out);
  ASSERT_TRUE(j);
  EXPECT_NEAR(j->at("data").at("truth_x").number, 4.0, 0.01) << "the chassis did not move: " << r.out;
  // A tool's MOVE gets the reason (exit 1: the component answered ERROR).
  r = ctl("", {"send", "chassis", "21"});
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "access denied by rule 'chassis-others': message type not allowed")) << r.describe();
  // Logged to GDOS at a bounded rate, with the last message refused.
  EXPECT_TRUE(rackd_->wait_for_stderr("access: rule 'chassis-others' refused", 10s)) << rackd_->err();
  EXPECT_TRUE(contains(rackd_->err(), "Pilot(0/0)#2 -> Chassis(0/0) type 21")) << rackd_->err();
  stop();
  EXPECT_TRUE(contains(rackd_->out(), "access rule 'chassis-others'")) << rackd_->out();
  EXPECT_FALSE(contains(rackd_->out(), "'chassis-others'  allowed 0, denied 0")) << rackd_->out();
}

TEST_F(AccessTest, AuthorisedPilotStillDrivesWithTheRulesInPlace) {
  start(sim_nav_with_access("pilot"), {"--lcm", url_});
  double x = 0;
  EXPECT_TRUE(eventually([&] {
    const RunResult r = ctl("", {"get-data", "chassis"});
    const auto j = parse_json(r.out);
    x = j ? j->at("data").at("truth_x").number : 0;
    return x > 4.3;
  })) << "truth_x "
      << x;
  const RunResult r = ctl("", {"status", "chassis", "--json"});
  const auto j = parse_json(r.out);
  ASSERT_TRUE(j) << r.describe();
  EXPECT_EQ(j->at("access_denied").number, 0) << r.out;
}

TEST_F(AccessTest, KeyFileReadableByOthersIsRefusedWithPathAndMode) {
  const std::string open_key = key_file("open.key", key_line('a'), 0644);
  const auto path = dir_.write("host.yaml", keyed_host(url_, open_key));
  RunResult r = run({kRackd, path.string()}, 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, "key file " + open_key + ": has mode 0644: group or others may access it"))
      << r.describe();
  r = run({kRackd, "--check", path.string()}, 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  r = ctl(open_key, {"list"});
  EXPECT_NE(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.err, "has mode 0644")) << r.describe();
  // rackctl keygen makes a file rackd accepts, and never overwrites one.
  const std::string made = (dir_.path() / "made.key").string();
  r = run({kRackctl, "keygen", made}, 10s);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  struct stat st {};
  ASSERT_EQ(stat(made.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  r = run({kRackctl, "keygen", made}, 10s);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "not overwritten")) << r.describe();
  r = run({kRackd, "--check", dir_.write("host2.yaml", keyed_host(url_, made)).string()}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
}

TEST_F(AccessTest, ToolWithoutTheKeyCannotCommandAKeyedHost) {
  const std::string key = key_file("robot.key", key_line('a'));
  const std::string wrong = key_file("wrong.key", key_line('b'));
  start(keyed_host(url_, key), {"--status", "1"});
  ASSERT_EQ(ctl(key, {"status", "Generator(0/0)"}).exit_code, 0);
  // A tool pointed at the host file takes its network and key file.
  const std::string host_file = (dir_.path() / "host0.yaml").string();
  RunResult r = run({kRackctl, "--host-file", host_file, "status", "generator"}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  r = run({kGdos, "--host-file", host_file, "--duration", "1"}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.err, "listening on " + url_)) << r.describe();
  EXPECT_TRUE(contains(r.err, ", 0 failed authentication")) << r.describe();
  r = run({kRackctl, "--host-file", (dir_.path() / "nosuch.yaml").string(), "list"}, 30s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  r = ctl("", {"off", "Generator(0/0)"}, "500");
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  r = ctl(wrong, {"off", "Generator(0/0)"}, "500");
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  r = ctl("", {"list"}, "500");
  EXPECT_EQ(r.exit_code, 3) << "discovery is authenticated too: " << r.describe();
  r = ctl(key, {"status", "Generator(0/0)", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "\"state\":\"ENABLED\"")) << r.out;
  stop();
  const std::string out = rackd_->out();
  const auto at = out.rfind("auth failed ");
  ASSERT_NE(at, std::string::npos) << out;
  EXPECT_GT(std::atoll(out.c_str() + at + 12), 0) << out;
  EXPECT_TRUE(contains(rackd_->err(), "not signed")) << rackd_->err();
  EXPECT_TRUE(contains(rackd_->err(), "signed with a key this host does not have")) << rackd_->err();
}

TEST_F(AccessTest, HostWithoutTheKeyInAnotherNetworkNamespaceCannotCommand) {
  if (const auto why = NetnsTopology::unsupported_reason()) GTEST_SKIP() << *why;
  NetnsTopology net(2);
  const std::string url = "udpm://239.255.76.67:" + std::to_string(bus_.port()) + "?ttl=1";
  const std::string key = key_file("robot.key", key_line('c'));
  const auto path = dir_.write("host.yaml", keyed_host(url, key));
  rackd_ = std::make_unique<Process>(std::vector<std::string>{kRackd, path.string(), "--status", "1"}, dir_.path(),
                                     "rackd-ns", net.host(0));
  ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  const auto remote = [&](const std::string& k, std::vector<std::string> args) {
    std::vector<std::string> head{kRackctl, "--lcm", url, "--discover-ms", "2000", "--timeout", "800"};
    if (!k.empty()) head.insert(head.end(), {"--key-file", k});
    args.insert(args.begin(), head.begin(), head.end());
    return run(args, 30s, net.host(1));
  };
  RunResult r = remote("", {"off", "Generator(0/0)"});
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  r = remote("", {"set-param", "Generator(0/0)", "amplitude", "9"});
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  // The same tool with the key, from the same namespace: it works, and nothing changed.
  r = remote(key, {"params", "Generator(0/0)", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "\"name\":\"amplitude\",\"kind\":\"float\",\"value\":2}")) << r.out;
  r = remote(key, {"status", "Generator(0/0)", "--json"});
  EXPECT_TRUE(contains(r.out, "\"state\":\"ENABLED\"")) << r.describe();
  stop();
}

TEST_F(AccessTest, CapturedPacketsReplayedWithLcmLogplayerAreDropped) {
  const std::string logger = find_tool("lcm-logger");
  const std::string player = find_tool("lcm-logplayer");
  if (logger.empty() || player.empty()) GTEST_SKIP() << "lcm-logger/lcm-logplayer not installed (liblcm-bin)";
  const std::string key = key_file("robot.key", key_line('d'));
  const std::string log = (dir_.path() / "capture.lcmlog").string();
  start(keyed_host(url_, key, "  replay_window_ms: 2000\n"), {"--status", "1"});
  {
    Process rec({logger, "--lcm-url=" + url_, "-f", log}, dir_.path(), "logger");
    std::this_thread::sleep_for(500ms);
    ASSERT_EQ(ctl(key, {"set-param", "Generator(0/0)", "amplitude", "6.5"}).exit_code, 0);
    std::this_thread::sleep_for(500ms);
    rec.signal(SIGINT);
    ASSERT_TRUE(rec.wait_exit(10s).has_value()) << rec.err();
  }
  ASSERT_EQ(ctl(key, {"set-param", "Generator(0/0)", "amplitude", "3"}).exit_code, 0);
  // Into the running host: every packet's sequence number was seen.
  RunResult play = run({player, "--lcm-url=" + url_, log}, 60s);
  ASSERT_EQ(play.exit_code, 0) << play.describe();
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(param(key, "amplitude"), 3.0);
  // Into a fresh host after the window: too old.
  stop();
  EXPECT_TRUE(contains(rackd_->err(), "sequence number already seen (replayed)")) << rackd_->err();
  const auto at = rackd_->out().rfind("replayed ");
  ASSERT_NE(at, std::string::npos);
  EXPECT_GT(std::atoll(rackd_->out().c_str() + at + 9), 0) << rackd_->out();
  std::this_thread::sleep_for(2500ms);
  start(keyed_host(url_, key, "  replay_window_ms: 2000\n"), {"--status", "1"});
  play = run({player, "--lcm-url=" + url_, log}, 60s);
  ASSERT_EQ(play.exit_code, 0) << play.describe();
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(param(key, "amplitude"), 2.0) << "the host file's value, not the captured 6.5";
  stop();
  EXPECT_TRUE(contains(rackd_->err(), "outside the replay window")) << rackd_->err();
}

TEST_F(AccessTest, KeyRotationKeepsTheSystemRunning) {
  const std::string a = key_line('a'), b = key_line('b');
  const std::string host_key = key_file("host.key", a);
  const std::string tool_a = key_file("a.key", a), tool_b = key_file("b.key", b);
  const std::string tool_ba = key_file("ba.key", b + a), tool_ab = key_file("ab.key", a + b);
  start(keyed_host(url_, host_key), {"--status", "1"});
  ASSERT_EQ(ctl(tool_a, {"status", "Generator(0/0)"}).exit_code, 0);
  // Step 1: every host accepts the new key too (still signing with the old one).
  key_file("host.key", a + b);
  ASSERT_TRUE(rackd_->wait_for_stderr("reloaded: 2 key(s)", 10s)) << rackd_->err();
  EXPECT_EQ(ctl(tool_a, {"status", "Generator(0/0)"}).exit_code, 0);
  EXPECT_EQ(ctl(tool_ba, {"status", "Generator(0/0)"}).exit_code, 0) << "signed with the new key: accepted";
  // Step 2: sign with the new key.
  key_file("host.key", b + a);
  std::this_thread::sleep_for(1500ms);
  EXPECT_EQ(ctl(tool_b, {"status", "Generator(0/0)"}).exit_code, 0);
  EXPECT_EQ(ctl(tool_ab, {"status", "Generator(0/0)"}).exit_code, 0);
  // Step 3: the old key is gone.
  key_file("host.key", b);
  std::this_thread::sleep_for(1500ms);
  EXPECT_EQ(ctl(tool_a, {"status", "Generator(0/0)"}, "500").exit_code, 3);
  const RunResult r = ctl(tool_b, {"status", "Generator(0/0)", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "\"state\":\"ENABLED\"")) << r.out;
  EXPECT_TRUE(rackd_->running());
  stop();
}

TEST_F(AccessTest, GdosViewerVerifiesTheLogWithTheKeyFile) {
  const std::string key = key_file("robot.key", key_line('e'));
  const std::string wrong = key_file("wrong.key", key_line('f'));
  start(keyed_host(url_, key));
  Process good({kGdos, "--lcm", url_, "--key-file", key, "--json", "--duration", "8"}, dir_.path(), "gdos-good");
  Process bad({kGdos, "--lcm", url_, "--key-file", wrong, "--json", "--duration", "8"}, dir_.path(), "gdos-bad");
  std::this_thread::sleep_for(1s);  // both viewers have joined
  // Each SET_PARAM of gdosLevel logs a print record ("log level now ...").
  for (const char* level : {"warning", "info", "warning"}) {
    ASSERT_EQ(ctl(key, {"set-param", "Generator(0/0)", "gdosLevel", level}).exit_code, 0);
  }
  ASSERT_EQ(good.wait_exit(20s), std::optional<int>(0)) << good.err();
  ASSERT_EQ(bad.wait_exit(20s), std::optional<int>(0)) << bad.err();
  EXPECT_TRUE(contains(good.out(), "log level now")) << good.out() << good.err();
  EXPECT_TRUE(contains(good.err(), ", 0 failed authentication")) << good.err();
  EXPECT_EQ(bad.out(), "") << "nothing shown that did not verify";
  EXPECT_TRUE(contains(bad.err(), "signed with a key this host does not have")) << bad.err();
  EXPECT_FALSE(contains(bad.err(), ", 0 failed authentication")) << bad.err();
}

}  // namespace
}  // namespace rack::test
