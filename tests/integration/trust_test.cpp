// Integration: whom data mailboxes trust, and subscriptions as leases (issue 17,
// rack/tims/trusted_sources.h, rack/core/data_component.h), against the real rackd on
// a private LCM bus:
//  - a tool (this test, a TiMS node of the tool system on the bus, as rackctl is)
//    sends forged samples and ERROR notifications and requests into the input
//    mailboxes of Position and Scan2D of the simulated robot: all refused and
//    counted, the requests answered NOT_AVAILABLE, and the whole pilot chain stays
//    ENABLED without one ERROR;
//  - 100 `rackctl watch` subscribers killed with SIGKILL leave no slot behind: after
//    one lease (1 s in this host file) a new subscriber gets data, while a consumer in
//    rackd and a `rackctl watch` that stay alive keep theirs by renewing;
//  - a consumer on another rackd keeps its subscription over many short leases.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "rack/components/class_ids.h"
#include "rack/core/wire.h"
#include "rack/rt/clock.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/router.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;
using tims::Address;
namespace msg = tims::msg;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A TiMS node of the tool system on the bus, as rackctl is, that sends what the test
// asks (any type, any destination mailbox) from its own address.
class Tool {
 public:
  static constexpr Address kAddress = Address::make(tims::kToolSystem, tims::classes::kTool, 0xEE, 0x10);

  explicit Tool(const std::string& url)
      : router_(tims::kToolSystem),
        reply_(kAddress, 64, 64 * 1024),
        endpoint_(router_, reply_, 10),
        transport_(router_, config(url)) {
    router_.add(reply_);
    transport_.start();
    transport_.wait_until_warm();
  }
  ~Tool() {
    transport_.stop();
    router_.remove(reply_.address());
  }
  Tool(const Tool&) = delete;
  Tool& operator=(const Tool&) = delete;

  void send(Address dest, int8_t type, std::span<const tims::ConstBuffer> body = {}) {
    (void)endpoint_.send(dest, type, body);
    // Paced: the uplink drops its oldest message when full; this is not a flood test.
    (void)transport_.wait_uplink(8, rt::kNsPerSec);
  }
  // A request and its reply's type (0: no reply within 3 s).
  int8_t call(Address dest, int8_t type) {
    std::vector<std::byte> buf(64 * 1024);
    const auto r = endpoint_.call(dest, type, buf, 3 * rt::kNsPerSec);
    return r.status == tims::CallStatus::kOk ? r.reply.type : int8_t{0};
  }

 private:
  static tims::LcmTransportConfig config(const std::string& url) {
    tims::LcmTransportConfig c;
    c.url = url;
    c.role = tims::NodeRole::kTool;
    c.announce_period_ns = 0;
    c.uplink_slots = 32;
    c.warn = [](const std::string&) {};
    return c;
  }

  tims::Router router_;
  tims::Mailbox reply_;
  tims::Endpoint endpoint_;
  tims::LcmTransport transport_;
};

class TrustTest : public ::testing::Test {
 protected:
  TrustTest() : watchdog_(110s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void TearDown() override {
    if (rackd_ && rackd_->running()) {
      rackd_->signal(SIGTERM);
      EXPECT_EQ(rackd_->wait_exit(30s), std::optional<int>(0)) << rackd_->err();
    }
  }

  void start(const std::string& path) {
    rackd_ = std::make_unique<Process>(std::vector<std::string>{kRackd, path, "--lcm", bus_.url()}, dir_.path(),
                                       "rackd");
    ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  }
  std::vector<std::string> ctl_args(std::vector<std::string> args) const {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url(), "--discover-ms", "3000"});
    return args;
  }
  RunResult ctl(std::vector<std::string> args) { return run(ctl_args(std::move(args)), 30s); }
  // `rackctl status NAME --json`, parsed (nullopt when it failed).
  std::optional<Json> status(const std::string& name) {
    const RunResult r = ctl({"status", name, "--json"});
    if (r.exit_code != 0) return std::nullopt;
    return parse_json(r.out);
  }
  double stat(const std::string& name, const std::string& key) {
    const auto j = status(name);
    return j && j->at(key).is_number() ? j->at(key).number : -1.0;
  }
  std::string state(const std::string& name) {
    const auto j = status(name);
    return j && j->at("state").is_string() ? j->at("state").string : "?";
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::unique_ptr<Process> rackd_;
};

// configs/sim_nav.yaml with absolute map paths.
std::string sim_nav_text() {
  std::string text = read_file(kConfigs + "/sim_nav.yaml");
  const std::string rel = "map: maps/office.yaml";
  for (auto at = text.find(rel); at != std::string::npos; at = text.find(rel, at + 1)) {
    text.replace(at, rel.size(), "map: " + kConfigs + "/maps/office.yaml");
  }
  return text;
}

TEST_F(TrustTest, ForgedInputAndRequestsIntoDataMailboxesLeaveThePilotChainEnabled) {
  start(dir_.write("sim_nav.yaml", sim_nav_text()).string());
  const std::vector<std::string> chain = {"chassis", "odometry", "position", "ladar", "scan2d", "path", "pilot"};
  ASSERT_TRUE(eventually([&] { return state("pilot") == "ENABLED"; }, 30s)) << rackd_->err();
  for (const auto& c : chain) ASSERT_EQ(state(c), "ENABLED") << c;
  double errors_before = 0;
  for (const auto& c : chain) errors_before += stat(c, "errors");
  const Address position = Address::make(0, class_ids::kPosition, 0);
  const Address scan2d = Address::make(0, class_ids::kScan2d, 0);

  Tool tool(bus_.url());
  // A sample the right size for Position's input (SampleHeader + OdometryData: six
  // doubles, two uint32), placing the robot 1 km away: taken, it would move the pose.
  struct FakeOdometry {
    wire::SampleHeader sh;
    double x = 1000.0, y = 1000.0, phi = 0.0, vx = 0.0, omega = 0.0, distance = 0.0;
    uint32_t resets = 0, pad = 0;
  } fake{{rt::host_time_ns(), 1}};
  const uint8_t junk[24] = {};
  wire::ErrorText text;
  wire::copy_text(text.text, "producer left ENABLED");
  const tims::ConstBuffer fake_part = tims::buffer_of(fake);
  const tims::ConstBuffer junk_part{junk, sizeof junk};
  const tims::ConstBuffer error_part = tims::buffer_of(text);
  constexpr int kEach = 10;
  for (const Address dest : {position, scan2d}) {
    const Address input = dest.with_mailbox(3);
    for (int i = 0; i < kEach; ++i) {
      tool.send(input, msg::kData, std::span<const tims::ConstBuffer>(&fake_part, 1));
      tool.send(input, msg::kData, std::span<const tims::ConstBuffer>(&junk_part, 1));
      tool.send(input, msg::kError, std::span<const tims::ConstBuffer>(&error_part, 1));
    }
    // A request into a data mailbox: answered NOT_AVAILABLE, never the component's state.
    EXPECT_EQ(tool.call(input, msg::kGetStatus), msg::kNotAvailable) << dest.str();
    for (int i = 0; i < kEach - 1; ++i) tool.send(input, msg::kGetStatus);
  }
  for (const char* name : {"position", "scan2d"}) {
    EXPECT_TRUE(eventually([&] { return stat(name, "input_forged") == 3 * kEach; }, 10s))
        << name << ": input_forged " << stat(name, "input_forged");
    EXPECT_TRUE(eventually([&] { return stat(name, "input_requests") == kEach; }, 10s))
        << name << ": input_requests " << stat(name, "input_requests");
  }
  // The refusals reach the log (GDOS, bounded rate), naming the tool's address.
  EXPECT_TRUE(eventually([&] { return contains(rackd_->err(), "not from a subscribed producer"); }, 10s))
      << rackd_->err();
  // Over a while longer than every data timeout of the chain: all still ENABLED, not
  // one transition into ERROR, and the pose is not where the forged sample put it.
  std::this_thread::sleep_for(2s);
  double errors_after = 0;
  for (const auto& c : chain) {
    EXPECT_EQ(state(c), "ENABLED") << c;
    errors_after += stat(c, "errors");
  }
  EXPECT_EQ(errors_after, errors_before) << rackd_->err();
  const RunResult pose = ctl({"get-data", "position"});
  ASSERT_EQ(pose.exit_code, 0) << pose.describe();
  const auto j = parse_json(pose.out);
  ASSERT_TRUE(j.has_value()) << pose.out;
  EXPECT_LT(j->at("data").at("x").number, 100.0) << pose.out;
}

// The leak test of issue 17: kill 100 `rackctl watch` subscribers (SIGKILL: no
// STOP_CONT_DATA), then subscribe once more and get data, within a lease.
TEST_F(TrustTest, KilledWatchersFreeTheirSlotsWithinOneLease) {
  constexpr int kLeaseMs = 1000;
  start(dir_.write("leak.yaml", R"(host: leak
system: 0
lcm: true
components:
  - name: generator
    class: Generator
    instance: 0
    data_task: {period_ms: 10, max_listeners: 16, lease_ms: )" +
                                    std::to_string(kLeaseMs) +
                                    R"(}
  - name: monitor
    class: Monitor
    instance: 0
    autostart: true
    params: {source: generator, source_period_ms: 10, silence_ms: 500}
)")
            .string());
  ASSERT_TRUE(eventually([&] { return state("monitor") == "ENABLED"; }, 30s)) << rackd_->err();
  const double monitor_errors = stat("monitor", "errors");
  const std::string producer = "Generator(0/0)";  // an address: no discovery per watcher
  // One watcher that stays alive through it all: it keeps its slot by renewing.
  Process keeper(ctl_args({"watch", producer, "--period", "100"}), dir_.path(), "keeper");
  ASSERT_TRUE(keeper.wait_for_stderr("watching", 20s)) << keeper.err();

  constexpr int kBatches = 10, kPerBatch = 10;
  int subscribed = 0;
  // rackctl's address comes from its pid with bit 0 cleared (tools/rackctl): two
  // watchers whose pids differ only there share a mailbox, and so one listener.
  std::set<int> addresses;
  for (int b = 0; b < kBatches; ++b) {
    // Room for a batch: the slots of the batch before are freed once their lease ran out.
    ASSERT_TRUE(eventually([&] { return stat("generator", "listeners") <= 16 - kPerBatch; }, 20s))
        << "listeners " << stat("generator", "listeners");
    std::vector<std::unique_ptr<Process>> batch;
    for (int i = 0; i < kPerBatch; ++i) {
      batch.push_back(std::make_unique<Process>(ctl_args({"watch", producer}), dir_.path(),
                                                "watch" + std::to_string(b * kPerBatch + i)));
    }
    for (auto& p : batch) {
      ASSERT_TRUE(p->wait_for_stderr("watching", 20s)) << p->err();
      ++subscribed;
    }
    for (auto& p : batch) addresses.insert((p->pid() & ~1) + b * (1 << 24));
    for (auto& p : batch) p->signal(SIGKILL);
    for (auto& p : batch) (void)p->wait_exit(10s);
  }
  EXPECT_EQ(subscribed, kBatches * kPerBatch);
  // Once more, within a lease (and a second's slack for the tools to start): data.
  RunResult again;
  EXPECT_TRUE(eventually(
      [&] {
        again = ctl({"watch", producer, "--count", "3"});
        return again.exit_code == 0;
      },
      std::chrono::milliseconds(kLeaseMs + 3000)))
      << again.describe();
  EXPECT_EQ(std::count(again.out.begin(), again.out.end(), '\n'), 3) << again.out;
  // Every dead listener expired (more than the slots could ever hold at once); the
  // monitor and the keeper are the two left, and neither lost its subscription.
  EXPECT_TRUE(
      eventually([&] { return stat("generator", "listeners") == 2; }, std::chrono::milliseconds(kLeaseMs + 3000)));
  const double expired = stat("generator", "listeners_expired");
  EXPECT_GE(expired, static_cast<double>(addresses.size())) << "one expiry per dead mailbox";
  EXPECT_GT(expired, 16) << "more than the slots could hold at once";
  std::printf("leak test: %d watchers subscribed and killed (%zu distinct mailboxes), %.0f listeners expired, 2 left\n",
              subscribed, addresses.size(), expired);
  EXPECT_EQ(stat("monitor", "errors"), monitor_errors);
  EXPECT_EQ(state("monitor"), "ENABLED");
  ASSERT_TRUE(keeper.running()) << keeper.err();
  const std::size_t lines = keeper.out().size();
  EXPECT_TRUE(eventually([&] { return keeper.out().size() > lines; }, 5s)) << "the keeper still gets samples";
  keeper.signal(SIGTERM);
  EXPECT_EQ(keeper.wait_exit(10s), std::optional<int>(0)) << keeper.err();
}

// Two rackd on one bus (one robot, two computers): the monitor on host b renews its
// subscription to the generator on host a over LCM every lease / 4 (here 100 ms), so
// over many leases it never loses it, and the generator never expires it.
TEST_F(TrustTest, AConsumerOnAnotherHostKeepsItsLeaseByRenewing) {
  const auto host = [&](int id, const std::string& components) {
    return "host: trust-" + std::to_string(id) + "\nsystem: 0\nhost_id: " + std::to_string(id) +
           "\nlcm: true\nlcm_url: \"" + bus_.url() + "\"\ntims: {announce_ms: 300, expiry_ms: 1500}\ncomponents:\n" +
           components;
  };
  Process a({kRackd, dir_.write("a.yaml", host(0, R"(  - name: generator
    class: Generator
    instance: 0
    autostart: true
    data_task: {period_ms: 10, lease_ms: 400}
)"))
                         .string()},
            dir_.path(), "rackd-a");
  ASSERT_TRUE(a.wait_for_stderr("rackd: running", 30s)) << a.err();
  rackd_ = std::make_unique<Process>(std::vector<std::string>{kRackd, dir_.write("b.yaml", host(1, R"(  - name: monitor
    class: Monitor
    instance: 0
    autostart: true
    params: {source: Generator(0/0), source_period_ms: 10, silence_ms: 1000}
)"))
                                                                          .string()},
                                     dir_.path(), "rackd-b");
  ASSERT_TRUE(rackd_->wait_for_stderr("rackd: running", 30s)) << rackd_->err();
  ASSERT_TRUE(eventually([&] { return state("monitor") == "ENABLED"; }, 30s)) << rackd_->err();
  const double errors = stat("monitor", "errors");
  const double received = [&] {
    const RunResult r = ctl({"get-data", "monitor"});
    const auto j = parse_json(r.out);
    return j ? j->at("data").at("received").number : -1.0;
  }();
  std::this_thread::sleep_for(3s);  // 7 leases
  EXPECT_EQ(state("monitor"), "ENABLED") << rackd_->err();
  EXPECT_EQ(stat("monitor", "errors"), errors) << rackd_->err();
  EXPECT_EQ(stat("generator", "listeners"), 1) << a.err();
  EXPECT_EQ(stat("generator", "listeners_expired"), 0) << a.err();
  EXPECT_EQ(stat("monitor", "input_forged"), 0);
  const RunResult r = ctl({"get-data", "monitor"});
  const auto j = parse_json(r.out);
  ASSERT_TRUE(j.has_value()) << r.describe();
  EXPECT_GT(j->at("data").at("received").number, received + 100) << "samples kept flowing";
  a.signal(SIGTERM);
  EXPECT_EQ(a.wait_exit(30s), std::optional<int>(0)) << a.err();
}

}  // namespace
}  // namespace rack::test
