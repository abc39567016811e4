// Tools under fan-out (issue 17, requirement 5): the real rackctl against three real
// rackd hosts with 30 components in all, on a private LCM bus.
//
//  - `rackctl list` gets the state of every component of every host in 100 of 100
//    runs, quiet and while this test floods the bus with packets every host refuses
//    (garbage, broken TiMS packets, requests with a forged source), bounded in count
//    and time;
//  - 20 rackctl started at once hold 20 distinct tool addresses (none reports another
//    one's packets as forged) and each gets its own component's parameters.
//
// Assertions are on behaviour (every row answered, the right answers); the runs' wall
// time is printed, never asserted.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "raw_lcm.h"
#include "rack/components/class_ids.h"
#include "rack/tims/message.h"
#include "rack/tims/router.h"
#include "rack_lcm/tims_packet.hpp"

namespace rack::test {
namespace {

using namespace std::chrono_literals;
using tims::Address;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;

constexpr int kHosts = 3;
constexpr int kPerHost = 10;
constexpr int kRuns = 100;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string component_name(int host, int i) { return "gen" + std::to_string(host) + "-" + std::to_string(i); }

// Host `host` of the three: 10 Generators (instances host*10..host*10+9), every other
// one switched on, with a 100 ms period (the machine is shared; the fan-out is what
// is tested, not the load).
std::string host_file(int host) {
  std::string t = "host: fanout-" + std::to_string(host) + "\nsystem: 0\nhost_id: " + std::to_string(host) +
                  "\nheap_prefault_mib: 0\ntims:\n  announce_ms: 300\n  expiry_ms: 3000\ncomponents:\n";
  for (int i = 0; i < kPerHost; ++i) {
    t += "  - name: " + component_name(host, i) +
         "\n    class: Generator\n    instance: " + std::to_string(host * kPerHost + i) +
         "\n    autostart: " + (i % 2 == 0 ? "true" : "false") +
         "\n    command_task: {priority: 30}\n    data_task: {priority: 40, period_ms: 100}\n"
         "    params: {amplitude: " +
         std::to_string(host * kPerHost + i + 1) + ".0}\n";
  }
  return t;
}

// One tims_packet holding a whole TiMS message (see tims/lcm/rack_tims.lcm).
std::vector<uint8_t> tims_packet(const std::vector<uint8_t>& message, int64_t origin, int32_t seq,
                                 int32_t total_override = -1) {
  std::vector<uint8_t> p;
  put64(p, static_cast<uint64_t>(rack_lcm::tims_packet::getHash()));
  put64(p, static_cast<uint64_t>(origin));
  put64(p, 0);  // relay
  put32(p, static_cast<uint32_t>(seq));
  put32(p, static_cast<uint32_t>(seq));
  const auto total = static_cast<uint32_t>(total_override >= 0 ? total_override : static_cast<int32_t>(message.size()));
  put32(p, total);
  put32(p, total);
  put32(p, 0);     // offset
  p.push_back(0);  // encoding
  p.push_back(0);  // hops
  put32(p, static_cast<uint32_t>(message.size()));
  p.insert(p.end(), message.begin(), message.end());
  return p;
}

std::vector<uint8_t> request(Address dest, Address src, int8_t type, uint8_t seq) {
  const tims::MessageHeader h = tims::make_header(dest, src, type, 1, seq, 0);
  std::vector<uint8_t> m(sizeof h);
  tims::encode_header(h, true, reinterpret_cast<std::byte*>(m.data()));
  return m;
}

// Sends packets every rackd and every rackctl refuses, about `rate` a second, until
// stopped or `limit` packets were sent.
class Flood {
 public:
  Flood(int port, int rate, uint64_t limit) : raw_(port) {
    thread_ = std::thread([this, rate, limit] { run(rate, limit); });
  }
  ~Flood() {
    stop_ = true;
    thread_.join();
  }
  Flood(const Flood&) = delete;
  Flood& operator=(const Flood&) = delete;
  [[nodiscard]] uint64_t sent() const { return sent_.load(); }

 private:
  void run(int rate, uint64_t limit) {
    std::mt19937 rng(17);
    const auto bytes = [&](std::size_t n) {
      std::vector<uint8_t> v(n);
      for (auto& b : v) b = static_cast<uint8_t>(rng());
      return v;
    };
    constexpr int kBurst = 20;
    const auto pause = std::chrono::microseconds(1'000'000LL * kBurst / rate);
    // A component of host 0 as the source of requests that another origin sends: forged.
    const Address owned = Address::make(0, class_ids::kGenerator, 0, 0);
    int32_t seq = 1;
    while (!stop_ && sent_ < limit) {
      for (int i = 0; i < kBurst; ++i) {
        switch (rng() % 5) {
          case 0: raw_.send_raw(bytes(8 + rng() % 200)); break;                            // not LCM
          case 1: raw_.send("TIMS", bytes(rng() % 300)); break;                            // not a tims_packet
          case 2: raw_.send("TIMS", tims_packet(bytes(16), 0x0bad, seq, 1 << 30)); break;  // lying length
          case 3: {  // a request in the name of a component its host owns
            const Address dest = Address::make(0, class_ids::kGenerator, static_cast<uint8_t>(10 + rng() % 20), 0);
            raw_.send("TIMS", tims_packet(request(dest, owned, 3, static_cast<uint8_t>(seq)), 0x0bad, seq));
            break;
          }
          default: raw_.send("TIMS", tims_packet(bytes(rng() % 15), 0x0bad, seq)); break;  // shorter than a header
        }
        ++seq;
        ++sent_;
      }
      std::this_thread::sleep_for(pause);
    }
  }

  RawLcm raw_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> sent_{0};
  std::thread thread_;
};

class ToolsFanoutTest : public ::testing::Test {
 protected:
  ToolsFanoutTest() : watchdog_(230s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void SetUp() override {
    for (int h = 0; h < kHosts; ++h) {
      const auto path = dir_.write("host" + std::to_string(h) + ".yaml", host_file(h));
      auto p = std::make_unique<Process>(std::vector<std::string>{kRackd, path.string(), "--lcm", bus_.url(),
                                                                  "--status", "2"},
                                         dir_.path(), "rackd" + std::to_string(h));
      ASSERT_TRUE(p->wait_for_stderr("rackd: running", 30s)) << p->err();
      rackd_.push_back(std::move(p));
    }
  }
  void TearDown() override {
    for (auto& p : rackd_) {
      if (p->running()) {
        p->signal(SIGTERM);
        EXPECT_EQ(p->wait_exit(30s), std::optional<int>(0)) << p->err();
      }
    }
  }
  RunResult ctl(std::vector<std::string> args) {
    args.insert(args.begin(), {kRackctl, "--lcm", bus_.url()});
    return run(args, 30s);
  }

  // One `rackctl list --json`: "" when every one of the 30 components is there with
  // the state its host file gives it, else what was wrong.
  std::string check_list() {
    const RunResult r = ctl({"list", "--json"});
    if (r.exit_code != 0) return "exit " + r.describe();
    const auto j = parse_json(r.out);
    if (!j || j->type != Json::Type::kArray) return "not a JSON array: " + r.out;
    std::set<std::string> seen;
    std::string bad;
    for (const auto& row : j->array) {
      const std::string name = row.at("name").string;
      const std::string state = row.at("state").string;
      // gen<h>-<i>: even i autostarts.
      const int i = name.size() > 5 ? std::atoi(name.c_str() + name.find('-') + 1) : -1;
      const std::string want = i % 2 == 0 ? "ENABLED" : "DISABLED";
      if (state != want) bad += " " + name + "=" + state;
      seen.insert(name);
    }
    if (seen.size() != static_cast<std::size_t>(kHosts * kPerHost)) {
      bad += " only " + std::to_string(seen.size()) + " components listed";
    }
    return bad.empty() ? "" : bad + "\n" + r.err;
  }

  void hundred_lists(const char* what) {
    int good = 0;
    std::vector<std::string> failures;
    const auto start = std::chrono::steady_clock::now();
    for (int run = 0; run < kRuns; ++run) {
      const std::string bad = check_list();
      if (bad.empty()) ++good;
      else if (failures.size() < 5) failures.push_back("run " + std::to_string(run) + ":" + bad);
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("%s: %d of %d lists complete, %.1f s (%.2f s a run)\n", what, good, kRuns, s, s / kRuns);
    std::string all;
    for (const auto& f : failures) all += f + "\n";
    EXPECT_EQ(good, kRuns) << all;
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
  std::vector<std::unique_ptr<Process>> rackd_;
};

TEST_F(ToolsFanoutTest, ListGetsEveryComponentOfThreeHostsIn100Runs) { hundred_lists("quiet bus"); }

TEST_F(ToolsFanoutTest, ListGetsEveryComponentIn100RunsDuringAFloodOfRefusedPackets) {
  uint64_t sent = 0;
  {
    Flood flood(bus_.port(), 4000, 2'000'000);  // bounded: at most 2 M packets, and the runs' time
    hundred_lists("flooded bus");
    sent = flood.sent();
  }
  std::printf("flood: %llu packets sent\n", static_cast<unsigned long long>(sent));
  EXPECT_GT(sent, 1000u);
  // Every host stayed up and counted what it refused (its status line, every 2 s).
  std::this_thread::sleep_for(2500ms);
  for (auto& p : rackd_) {
    ASSERT_TRUE(p->running()) << p->err();
    const std::string out = p->out();
    const auto malformed = out.rfind(" malformed ");
    ASSERT_NE(malformed, std::string::npos) << out;
    EXPECT_GT(std::strtoull(out.c_str() + malformed + 11, nullptr, 10), 0u) << out.substr(malformed, 200);
  }
}

TEST_F(ToolsFanoutTest, TwentyRackctlStartedAtOnceHoldDistinctAddressesAndGetTheirOwnAnswers) {
  // Each asks for one component's parameters; the amplitude tells whose answer came.
  constexpr int kTools = 20;
  std::vector<std::thread> threads;
  std::vector<RunResult> results(kTools);
  for (int k = 0; k < kTools; ++k) {
    threads.emplace_back([&, k] {
      results[static_cast<std::size_t>(k)] = ctl(
          {"--discover-ms", "3000", "params", component_name(k % kHosts, k % kPerHost), "--json"});
    });
  }
  for (auto& t : threads) t.join();
  for (int k = 0; k < kTools; ++k) {
    const RunResult& r = results[static_cast<std::size_t>(k)];
    ASSERT_EQ(r.exit_code, 0) << "rackctl " << k << ": " << r.describe();
    EXPECT_FALSE(contains(r.err, "forged")) << "rackctl " << k << " shares its address: " << r.err;
    const int instance = (k % kHosts) * kPerHost + k % kPerHost;
    const std::string amplitude = std::to_string(instance + 1);
    EXPECT_TRUE(contains(r.out, "\"amplitude\"")) << r.out;
    const auto at = r.out.find("\"amplitude\"");
    const auto value = r.out.find("\"value\":", at);
    ASSERT_NE(value, std::string::npos) << r.out;
    EXPECT_EQ(std::atof(r.out.c_str() + value + 8), static_cast<double>(instance + 1)) << r.out;
  }
}

}  // namespace
}  // namespace rack::test
