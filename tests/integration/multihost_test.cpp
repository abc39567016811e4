// Multi-host integration tests: real rackd processes, each in a network namespace of
// its own ("hosts" on one bridge), talking TiMS over real LCM multicast (ttl=1), driven
// by the real rackctl from inside a namespace, as an operator on one of the computers.
//
// They need root (namespaces) and skip with the reason otherwise. Every test has a
// watchdog; the namespaces are deleted by the fixture (and, after a crash, by the next
// run). Assertions are on behaviour (states, replies, data flowing); waits are bounded
// generously and only turn a hang into a failure.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <memory>
#include <optional>
#include <sstream>
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
const std::string kConfigs = RACK_CONFIGS_DIR;

constexpr auto kTestLimit = 110s;
constexpr auto kCommandLimit = 30s;
constexpr auto kStartLimit = 30s;
constexpr auto kSettleLimit = 20s;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Discovery fast enough for tests: announce every 300 ms, expire after 1.5 s.
constexpr int kAnnounceMs = 300;
constexpr int kExpiryMs = 1500;

std::string tims_section(const std::string& url) {
  return "tims:\n  announce_ms: " + std::to_string(kAnnounceMs) + "\n  expiry_ms: " + std::to_string(kExpiryMs) +
         "\n  networks:\n    - {name: robot, url: \"" + url + "\", scope: robot}\n";
}

// Host a: the producer. Host b and c: a monitor each, subscribed to a's generator.
// The monitors' data timeout is long (60 s): when they go to ERROR sooner, it is the
// transport's expiry that told them.
std::string producer_host(const std::string& url) {
  return "host: host-a\nsystem: 0\nhost_id: 0\nheap_prefault_mib: 0\n" + tims_section(url) +
         R"(components:
  - name: generator
    class: Generator
    instance: 0
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 60, period_ms: 10}
    params: {amplitude: 2.0}
)";
}

std::string consumer_host(const std::string& url, int host_id, int instance) {
  return "host: host-" + std::string(1, static_cast<char>('a' + host_id)) +
         "\nsystem: 0\nhost_id: " + std::to_string(host_id) + "\nheap_prefault_mib: 0\n" + tims_section(url) +
         "components:\n  - name: monitor" + std::to_string(instance) +
         "\n    class: Monitor\n    instance: " + std::to_string(instance) +
         R"yaml(
    autostart: true
    retry_ms: 300
    rpc_timeout_ms: 500
    command_task: {priority: 30}
    data_task: {priority: 50}
    params: {source: "Generator(0/0)", source_period_ms: 0, silence_ms: 60000}
)yaml";
}

class MultiHostTest : public ::testing::Test {
 protected:
  MultiHostTest() : watchdog_(kTestLimit, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  void SetUp() override {
    if (const auto why = NetnsTopology::unsupported_reason()) GTEST_SKIP() << *why;
    net_ = std::make_unique<NetnsTopology>(3);
    url_ = "udpm://239.255.76.67:" + std::to_string(bus_.port()) + "?ttl=1";
  }
  void TearDown() override {
    for (auto& p : rackd_) {
      if (p && p->running()) {
        p->signal(SIGTERM);
        EXPECT_EQ(p->wait_exit(kCommandLimit), std::optional<int>(0)) << p->err();
      }
    }
    rackd_.clear();
  }

  // rackd in host i's namespace, with this host file; waits until it runs.
  Process* start_host(int i, const std::string& text) {
    const auto path = dir_.write("host" + std::to_string(i) + ".yaml", text);
    const std::string tag = "rackd-h" + std::to_string(i) + "-" + std::to_string(starts_++);
    auto p = std::make_unique<Process>(std::vector<std::string>{kRackd, path.string(), "--status", "1"}, dir_.path(),
                                       tag, net_->host(i));
    if (!p->wait_for_stderr("rackd: running", kStartLimit)) {
      ADD_FAILURE() << "rackd on host " << i << " did not start:\n" << p->err();
      return nullptr;
    }
    rackd_.push_back(std::move(p));
    return rackd_.back().get();
  }
  void start_three() {
    ASSERT_NE(a_ = start_host(0, producer_host(url_)), nullptr);
    ASSERT_NE(start_host(1, consumer_host(url_, 1, 1)), nullptr);
    ASSERT_NE(start_host(2, consumer_host(url_, 2, 2)), nullptr);
  }

  // rackctl from host i's namespace.
  RunResult ctl(int i, std::vector<std::string> args, const std::string& discover_ms = "3000") {
    args.insert(args.begin(), {kRackctl, "--lcm", url_, "--discover-ms", discover_ms, "--timeout", "1000"});
    return run(args, kCommandLimit, net_->host(i));
  }
  std::string state_of(int from, const std::string& name) {
    const RunResult r = ctl(from, {"status", name, "--json"});
    if (r.exit_code != 0) return "";
    const auto j = parse_json(r.out);
    const Json* s = j ? j->get("state") : nullptr;
    return s != nullptr && s->is_string() ? s->string : "";
  }
  double number_of(int from, const std::string& name, const std::string& key) {
    const RunResult r = ctl(from, {"status", name, "--json"});
    if (r.exit_code != 0) return -1;
    const auto j = parse_json(r.out);
    const Json* v = j ? j->get(key) : nullptr;
    return v != nullptr && v->is_number() ? v->number : -1;
  }
  // The monitor's received-sample count grows (data flows across hosts).
  bool receiving(int from, const std::string& monitor) {
    const double before = number_of(from, monitor, "cycles");
    if (before < 0) return false;
    std::this_thread::sleep_for(300ms);
    return number_of(from, monitor, "cycles") > before;
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::unique_ptr<NetnsTopology> net_;  // destroyed after the processes below
  std::vector<std::unique_ptr<Process>> rackd_;
  Process* a_ = nullptr;
  std::string url_;
  int starts_ = 0;
};

TEST_F(MultiHostTest, RpcAndStreamsAcrossThreeHosts) {
  start_three();
  // Both monitors switched the remote generator on (cascading ON across hosts) and
  // receive its samples.
  ASSERT_TRUE(eventually([&] { return state_of(2, "monitor1") == "ENABLED"; }));
  ASSERT_TRUE(eventually([&] { return state_of(0, "monitor2") == "ENABLED"; }));
  EXPECT_TRUE(eventually([&] { return receiving(0, "monitor1"); }));
  EXPECT_TRUE(eventually([&] { return receiving(1, "monitor2"); }));

  // rackctl list on any host shows every component of every host.
  const RunResult list = ctl(2, {"list"}, "1000");
  ASSERT_EQ(list.exit_code, 0) << list.describe();
  for (const char* want : {"Generator(0/0)", "Monitor(0/1)", "Monitor(0/2)", "host-a", "host-b", "host-c"}) {
    EXPECT_TRUE(contains(list.out, want)) << want << "\n" << list.describe();
  }
  EXPECT_FALSE(contains(list.out, "no reply")) << list.describe();

  // Parameters and getData across hosts.
  RunResult r = ctl(1, {"set-param", "generator", "amplitude", "7.5"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  r = ctl(2, {"params", "generator", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "7.5")) << r.describe();
  r = ctl(2, {"get-data", "generator"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "\"value\"")) << r.describe();

  // A getContData stream from a host to a tool in another host's namespace.
  r = ctl(2, {"watch", "monitor1", "--count", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  int lines = 0;
  std::istringstream in(r.out);
  for (std::string l; std::getline(in, l);) lines += l.empty() ? 0 : 1;
  EXPECT_EQ(lines, 3) << r.describe();

  // OFF across hosts: the producer's listeners get ERROR, the monitors go to ERROR,
  // retry, switch the generator on again and receive again.
  r = ctl(1, {"off", "generator"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(eventually([&] { return state_of(0, "monitor1") == "ENABLED" && receiving(0, "monitor1"); }));
}

TEST_F(MultiHostTest, UnknownMailboxIsNotAvailableOnEveryHost) {
  start_three();
  for (int from = 0; from < 3; ++from) {
    const RunResult r = ctl(from, {"status", "Generator(0/9)"});
    EXPECT_EQ(r.exit_code, 3) << r.describe();
    EXPECT_TRUE(contains(r.err, "NOT_AVAILABLE")) << "from host " << from << ": " << r.describe();
  }
  const RunResult r = ctl(1, {"status", "Monitor(0/7)"});
  EXPECT_TRUE(contains(r.err, "NOT_AVAILABLE")) << r.describe();
  // Exactly one authority answered (host a, the lowest host id); the others did not.
  const auto answered = [](Process& p) {
    const std::string out = p.out();
    const auto at = out.rfind(" not available ");
    return at == std::string::npos ? -1 : std::atol(out.c_str() + at + 15);
  };
  EXPECT_TRUE(eventually([&] { return answered(*rackd_[0]) >= 4; }, 5s)) << rackd_[0]->out();
  std::this_thread::sleep_for(1200ms);  // every rackd printed its counters since (--status 1)
  EXPECT_EQ(answered(*rackd_[1]), 0) << rackd_[1]->out();
  EXPECT_EQ(answered(*rackd_[2]), 0) << rackd_[2]->out();
}

TEST_F(MultiHostTest, SigkillOfTheProducerHostAndRecovery) {
  start_three();
  ASSERT_TRUE(eventually([&] { return state_of(1, "monitor1") == "ENABLED" && receiving(1, "monitor1"); }));
  ASSERT_TRUE(eventually([&] { return state_of(2, "monitor2") == "ENABLED"; }));
  a_->signal(SIGKILL);
  ASSERT_TRUE(a_->wait_exit(kCommandLimit).has_value());
  // Within the expiry (1.5 s; the monitors' own data timeout is 60 s) the transport
  // tells each consumer: ERROR.
  EXPECT_TRUE(eventually([&] { return state_of(1, "monitor1") == "ERROR"; }, 15s));
  EXPECT_TRUE(eventually([&] { return state_of(2, "monitor2") == "ERROR"; }, 15s));
  EXPECT_TRUE(eventually([&] { return contains(rackd_[1]->err(), "expired"); }, 5s)) << rackd_[1]->err();
  // The other hosts keep running and answering.
  EXPECT_TRUE(rackd_[1]->running());
  EXPECT_TRUE(rackd_[2]->running());
  const RunResult r = ctl(2, {"status", "generator"}, "500");
  EXPECT_EQ(r.exit_code, 3) << r.describe();

  // The host comes back: the monitors re-subscribe by their own retry.
  ASSERT_NE(a_ = start_host(0, producer_host(url_)), nullptr);
  EXPECT_TRUE(eventually([&] { return state_of(1, "monitor1") == "ENABLED" && receiving(1, "monitor1"); }));
  EXPECT_TRUE(eventually([&] { return state_of(2, "monitor2") == "ENABLED" && receiving(2, "monitor2"); }));
}

TEST_F(MultiHostTest, ProducerStopsStreamingToAKilledConsumerHost) {
  start_three();
  ASSERT_TRUE(eventually([&] { return number_of(0, "generator", "listeners") == 2; }));
  rackd_[1]->signal(SIGKILL);  // host b, monitor1's host
  ASSERT_TRUE(rackd_[1]->wait_exit(kCommandLimit).has_value());
  // After the expiry the producer's host tells the generator to drop that listener;
  // host c's stream goes on.
  EXPECT_TRUE(eventually([&] { return number_of(0, "generator", "listeners") == 1; }, 15s));
  EXPECT_TRUE(receiving(2, "monitor2"));
  EXPECT_TRUE(contains(rackd_[0]->err(), "expired")) << rackd_[0]->err();
  rackd_.erase(rackd_.begin() + 1);  // nothing to stop there
}

TEST_F(MultiHostTest, TwoHostsWithTheSameHostIdAreReported) {
  ASSERT_NE(a_ = start_host(0, producer_host(url_)), nullptr);
  // A configuration error: host b also claims host id 0 of system 0.
  std::string text = consumer_host(url_, 1, 1);
  text.replace(text.find("host_id: 1"), 10, "host_id: 0");
  ASSERT_NE(start_host(1, text), nullptr);
  EXPECT_TRUE(eventually([&] { return contains(a_->err(), "own system 0 and host id 0"); }, 10s)) << a_->err();
  EXPECT_TRUE(contains(a_->err(), "give every computer of a robot its own host_id")) << a_->err();
  EXPECT_TRUE(a_->running());
}

TEST_F(MultiHostTest, LinkDownAndUp) {
  start_three();
  ASSERT_TRUE(eventually([&] { return state_of(1, "monitor1") == "ENABLED" && receiving(1, "monitor1"); }));
  net_->set_link(0, false);  // host a's cable out
  EXPECT_TRUE(eventually([&] { return state_of(1, "monitor1") == "ERROR"; }, 15s));
  EXPECT_TRUE(eventually([&] { return state_of(2, "monitor2") == "ERROR"; }, 15s));
  // b and c still reach each other; a still runs on its own.
  EXPECT_EQ(ctl(2, {"status", "monitor1"}).exit_code, 0);
  EXPECT_TRUE(a_->running());
  EXPECT_EQ(ctl(0, {"status", "generator"}).exit_code, 0);
  net_->set_link(0, true);
  EXPECT_TRUE(eventually([&] { return state_of(1, "monitor1") == "ENABLED" && receiving(1, "monitor1"); }));
  EXPECT_TRUE(eventually([&] { return state_of(2, "monitor2") == "ENABLED" && receiving(2, "monitor2"); }));
}

// ------------------------------------------------------------------ two robots

// The shipped example (configs/two_robots/): robot 1 (system router + sensor computer),
// robot 2 (system router with a consumer of robot 1's scanner), a base station with
// the top router. Each computer in its own namespace; the example's ports are
// replaced by this test's private ones.
class TwoRobotsTest : public MultiHostTest {
 protected:
  void SetUp() override {
    if (const auto why = NetnsTopology::unsupported_reason()) GTEST_SKIP() << *why;
    net_ = std::make_unique<NetnsTopology>(4);
  }
  std::string example(const std::string& name) {
    std::string text = read_file(kConfigs + "/two_robots/" + name);
    const auto swap = [&](const std::string& from, int port) {
      for (auto at = text.find(from); at != std::string::npos; at = text.find(from, at + 1)) {
        std::string to = ":";
        to += std::to_string(port);
        to += '?';
        text.replace(at, from.size(), to);
      }
    };
    swap(":7711?", robot1_.port());
    swap(":7712?", robot2_.port());
    swap(":7700?", fleet_.port());
    return text;
  }
  RunResult ctl_on(int host, const std::string& url, std::vector<std::string> args) {
    args.insert(args.begin(), {kRackctl, "--lcm", url, "--discover-ms", "3000", "--timeout", "1500"});
    return run(args, kCommandLimit, net_->host(host));
  }
  std::string state_on(int host, const std::string& url, const std::string& name) {
    const RunResult r = ctl_on(host, url, {"status", name, "--json"});
    const auto j = r.exit_code == 0 ? parse_json(r.out) : std::nullopt;
    const Json* v = j ? j->get("state") : nullptr;
    return v != nullptr && v->is_string() ? v->string : "";
  }
  double cycles_on(int host, const std::string& url, const std::string& name) {
    const RunResult r = ctl_on(host, url, {"status", name, "--json"});
    const auto j = r.exit_code == 0 ? parse_json(r.out) : std::nullopt;
    const Json* v = j ? j->get("cycles") : nullptr;
    return v != nullptr && v->is_number() ? v->number : -1;
  }
  // The last "packets in N" that a rackd printed in its status lines.
  static uint64_t packets_in(Process& p) {
    const std::string out = p.out();
    const auto at = out.rfind("packets in ");
    return at == std::string::npos ? 0 : std::strtoull(out.c_str() + at + 11, nullptr, 10);
  }
  std::string url(const LcmBus& bus) const { return "udpm://239.255.76.68:" + std::to_string(bus.port()) + "?ttl=1"; }
  std::string robot_url(const LcmBus& bus) const {
    return "udpm://239.255.76.67:" + std::to_string(bus.port()) + "?ttl=1";
  }

  LcmBus robot1_, robot2_, fleet_;
};

TEST_F(TwoRobotsTest, RoutersCarryFleetTrafficAndKeepRobotTrafficHome) {
  Process* base = start_host(3, example("base_station.yaml"));
  ASSERT_NE(base, nullptr);
  ASSERT_NE(start_host(1, example("robot1_aux.yaml")), nullptr);
  ASSERT_NE(start_host(0, example("robot1_main.yaml")), nullptr);
  ASSERT_NE(start_host(2, example("robot2_main.yaml")), nullptr);
  const std::string fleet = url(fleet_);
  const std::string robot1 = robot_url(robot1_);

  // Robot 1's internal consumer and robot 2's cross-robot consumer both run.
  EXPECT_TRUE(eventually([&] { return state_on(0, robot1, "nav-monitor") == "ENABLED"; }));
  EXPECT_TRUE(eventually([&] { return state_on(3, fleet, "fleet-monitor") == "ENABLED"; }));
  EXPECT_TRUE(eventually([&] {
    const double before = cycles_on(3, fleet, "fleet-monitor");
    std::this_thread::sleep_for(500ms);
    return before >= 0 && cycles_on(3, fleet, "fleet-monitor") > before;
  }));

  // From the base station (fleet link): every component of every robot, and RPC into
  // robot 1's internal bus through its system router.
  const RunResult list = ctl_on(3, fleet, {"list"});
  ASSERT_EQ(list.exit_code, 0) << list.describe();
  for (const char* want : {"Generator(1/0)", "Monitor(1/1)", "Monitor(2/0)", "robot1-aux", "robot2-main"}) {
    EXPECT_TRUE(contains(list.out, want)) << want << "\n" << list.describe();
  }
  EXPECT_FALSE(contains(list.out, "no reply")) << list.describe();
  const RunResult hosts = ctl_on(3, fleet, {"hosts"});
  ASSERT_EQ(hosts.exit_code, 0) << hosts.describe();
  for (const char* want : {"robot1-main", "robot1-aux", "robot2-main", "base-station", "system_router", "top_router"}) {
    EXPECT_TRUE(contains(hosts.out, want)) << want << "\n" << hosts.describe();
  }
  RunResult r = ctl_on(3, fleet, {"get-data", "scanner"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  // From robot 1's bus to robot 2 and back.
  r = ctl_on(1, robot1, {"status", "fleet-monitor"});
  EXPECT_EQ(r.exit_code, 0) << r.describe();

  // NOT_AVAILABLE: a robot nobody knows (the top router answers), a mailbox robot 1
  // does not have (robot 1's system router answers).
  r = ctl_on(3, fleet, {"status", "Generator(7/0)"});
  EXPECT_EQ(r.exit_code, 3) << r.describe();
  EXPECT_TRUE(contains(r.err, "NOT_AVAILABLE")) << r.describe();
  r = ctl_on(3, fleet, {"status", "Generator(1/9)"});
  EXPECT_TRUE(contains(r.err, "NOT_AVAILABLE")) << r.describe();
  r = ctl_on(1, robot1, {"status", "Generator(1/9)"});
  EXPECT_TRUE(contains(r.err, "NOT_AVAILABLE")) << r.describe();

  // Robot 1's 100 Hz internal stream stays off the fleet link: over the same few
  // seconds the top router hears far fewer TiMS packets than robot 1's internal
  // consumer receives samples (only robot 2's 10 Hz subscription crosses).
  std::this_thread::sleep_for(1500ms);
  const uint64_t fleet_before = packets_in(*base);
  const double internal_before = cycles_on(0, robot1, "nav-monitor");
  std::this_thread::sleep_for(3s);
  const uint64_t fleet_packets = packets_in(*base) - fleet_before;
  const double internal = cycles_on(0, robot1, "nav-monitor") - internal_before;
  EXPECT_GT(internal, 100) << "robot 1's internal stream is not flowing";
  EXPECT_LT(static_cast<double>(fleet_packets), internal / 2)
      << "fleet link carried " << fleet_packets << " TiMS packets while robot 1's consumer got " << internal;
}

// The shipped example as it runs, from the base station's fleet link with no host
// file (rackctl graph --live, issue 25): every host and component of both robots,
// the scanner's two subscriptions with the networks they cross (robot 1's bus inside
// robot 1; robot1 > fleet > robot2 through the system routers) and each task's
// priority and period as the host files configure them.
TEST_F(TwoRobotsTest, GraphFromDiscoveryAloneShowsFlowsNetworksAndTasksAsTheyRun) {
  ASSERT_NE(start_host(3, example("base_station.yaml")), nullptr);
  ASSERT_NE(start_host(1, example("robot1_aux.yaml")), nullptr);
  ASSERT_NE(start_host(0, example("robot1_main.yaml")), nullptr);
  ASSERT_NE(start_host(2, example("robot2_main.yaml")), nullptr);
  const std::string fleet = url(fleet_);
  const std::string internal = R"("consumer":"nav-monitor","consumer_host":"robot1-main","param":"",)";
  const std::string crossing = R"("consumer":"fleet-monitor","consumer_host":"robot2-main","param":"",)";
  std::string out;
  EXPECT_TRUE(eventually([&] {
    const RunResult r = ctl_on(3, fleet, {"graph", "--live", "--format", "json"});
    out = r.out;
    return r.exit_code == 0 && contains(out, internal) && contains(out, crossing);
  })) << out;
  for (const char* want :
       {R"("producer":"scanner","producer_host":"robot1-aux","period_ns":10000000,"networks":["robot1"],)",
        R"("producer":"scanner","producer_host":"robot1-aux","period_ns":100000000,)"
        R"("networks":["robot1","fleet","robot2"],)",
        R"("host":"robot1-aux","system":1,"host_id":1,"role":"executor","networks":[{"name":"robot1","scope":"robot",)",
        R"("host":"robot2-main","system":2,"host_id":0,"role":"system_router","networks":[{"name":"robot2",)",
        R"("host":"base-station",)", R"("name":"scanner","impl":"Generator")", R"("command_task":{"priority":30,)",
        R"("data_task":{"priority":60,)", R"("data_task":{"priority":50,)", R"("policy":"SCHED_FIFO","priority":60,)",
        R"("period_ns":10000000,"measured_period_ns":)"}) {
    EXPECT_TRUE(contains(out, want)) << want << "\n" << out;
  }
  EXPECT_FALSE(contains(out, R"("priority":null)")) << out;
}

}  // namespace
}  // namespace rack::test
