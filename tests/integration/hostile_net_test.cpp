// Hostile network input (issue 17): the real rackd, the real `gdos` viewer and the real
// `rackctl` on a private LCM bus, and this test as an attacker or a broken device that
// writes raw UDP multicast datagrams: LCM framing it makes up, LCM fragments, and
// announcements, discover requests, GDOS batches and listener messages whose strings
// have a length of 0 or less (lcm-gen's decoders threw std::length_error on those and
// aborted rackd and rackctl) or whose counts are absurd, truncated packets, floods.
//
// Each test checks that the process stays up, that rackd's components stay ENABLED
// and its periodic task keeps its rate (cycles over the interval against the period,
// with a generous tolerance, never a timing), that the tools still do their job, and
// that the counters say what was refused.
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
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "raw_lcm.h"
#include "shipped_host.h"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/gdos_batch.hpp"
#include "rack_lcm/gdos_listener.hpp"
#include "rack_lcm/host_announce.hpp"
#include "rack_lcm/tims_packet.hpp"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kGdos = RACK_GDOS_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

void put8(Bytes& d, uint8_t v) { d.push_back(v); }
// An lcm-gen string with the length field given (the bytes that follow are `text`).
void put_string(Bytes& d, int32_t length, const std::string& text = "") {
  put32(d, static_cast<uint32_t>(length));
  d.insert(d.end(), text.begin(), text.end());
}
void put_string(Bytes& d, const std::string& s) { put_string(d, static_cast<int32_t>(s.size() + 1), s + '\0'); }

// ---- the payloads (tims/lcm/*.lcm), field by field, so that any field can lie ----

Bytes discover(int64_t origin, int32_t requester_length, const std::string& requester_bytes = "") {
  Bytes d;
  put64(d, static_cast<uint64_t>(rack_lcm::discover_request::getHash()));
  put64(d, static_cast<uint64_t>(origin));
  put64(d, 0);  // relay
  put8(d, 0);   // hops
  put64(d, 0);  // time_ns
  put_string(d, requester_length, requester_bytes);
  return d;
}
Bytes good_discover(int64_t origin) {
  Bytes d = discover(origin, 6, std::string("flood") + '\0');
  return d;
}

struct Announce {
  int32_t count = 0;
  int64_t origin = 0xbad;
  int32_t host_length = 0;  // 0: the bug; else as given
  std::string host_bytes;
  int32_t system = 0;
  int32_t host_id = 7;
  std::vector<std::pair<int32_t, int32_t>> components;  // name and impl lengths
};
Bytes announce(const Announce& a) {
  Bytes d;
  put64(d, static_cast<uint64_t>(rack_lcm::host_announce::getHash()));
  put32(d, static_cast<uint32_t>(a.count));
  put64(d, static_cast<uint64_t>(a.origin));
  put64(d, 0);  // relay
  put8(d, 0);   // hops
  put8(d, 0);   // role
  put64(d, 0);  // time_ns
  put64(d, 1'000'000'000);
  put_string(d, a.host_length, a.host_bytes);
  put32(d, static_cast<uint32_t>(a.system));
  put32(d, static_cast<uint32_t>(a.host_id));
  put32(d, 4242);  // pid
  put32(d, 0x00010700);
  for (const auto& [name, impl] : a.components) {
    put32(d, 0x40070000);
    put_string(d, name, "x");
    put_string(d, impl, "y");
  }
  return d;
}
Bytes good_announce(int64_t origin, int32_t system, int32_t host_id) {
  Announce a;
  a.origin = origin;
  a.host_length = 5;
  a.host_bytes = std::string("fake") + '\0';
  a.system = system;
  a.host_id = host_id;
  return announce(a);
}

Bytes gdos_batch(int32_t host_length, int32_t count, int32_t text_length) {
  Bytes d;
  put64(d, static_cast<uint64_t>(rack_lcm::gdos_batch::getHash()));
  put64(d, 0);
  put_string(d, host_length, host_length > 0 ? std::string(static_cast<std::size_t>(host_length - 1), 'h') + '\0' : "");
  put32(d, 1);  // pid
  put32(d, static_cast<uint32_t>(count));
  if (count > 0) {  // one record, whatever the count says
    put64(d, 0);
    put64(d, 1);
    put32(d, 0x40000000);
    put_string(d, "generator");
    put8(d, 3);
    put32(d, 0);
    put_string(d, text_length, "forged record");
  }
  return d;
}

Bytes gdos_listener(int32_t name_length) {
  Bytes d;
  put64(d, static_cast<uint64_t>(rack_lcm::gdos_listener::getHash()));
  put64(d, 0);
  put_string(d, name_length, "");
  put32(d, 1);
  return d;
}

Bytes tims_packet_claiming(int32_t size_field, std::size_t bytes) {
  Bytes d;
  put64(d, static_cast<uint64_t>(rack_lcm::tims_packet::getHash()));
  put64(d, 0x5eed);
  put64(d, 0);
  put32(d, 1);
  put32(d, 1);
  put32(d, 0x7fffffff);  // total
  put32(d, 0x7fffffff);  // encoded
  put32(d, 0);
  put8(d, 0);
  put8(d, 0);
  put32(d, static_cast<uint32_t>(size_field));
  d.resize(d.size() + bytes, 0);
  return d;
}

// One round of every kind of hostile datagram; returns how many were sent.
int send_hostile_round(RawLcm& raw, std::mt19937& rng) {
  int sent = 0;
  const auto send = [&](const std::string& ch, const Bytes& p) {
    raw.send(ch, p);
    ++sent;
  };
  // Discover requests whose string length is 0, -1, INT32_MIN, or beyond the datagram.
  for (const int32_t len : {0, -1, INT32_MIN, 1000}) send("TIMS_DISCOVER", discover(0x1001, len));
  Bytes truncated = good_discover(0x1002);
  truncated.resize(20);
  send("TIMS_DISCOVER", truncated);
  // Announcements: host length 0 and negative, a component name of length 0, counts
  // negative and absurd, truncated.
  for (const int32_t len : {0, -5}) {
    Announce a;
    a.host_length = len;
    send("TIMS_ANNOUNCE", announce(a));
  }
  Announce comp;
  comp.count = 1;
  comp.host_length = 2;
  comp.host_bytes = std::string("h") + '\0';
  comp.components = {{0, 2}};
  send("TIMS_ANNOUNCE", announce(comp));
  for (const int32_t count : {-1, 0x7fffffff}) {
    Announce a;
    a.count = count;
    a.host_length = 2;
    a.host_bytes = std::string("h") + '\0';
    send("TIMS_ANNOUNCE", announce(a));
  }
  Bytes short_announce = good_announce(0x1003, 0, 9);
  short_announce.resize(30);
  send("TIMS_ANNOUNCE", short_announce);
  // GDOS: batches with a host or text length of 0 and absurd counts, listener
  // messages with a name length of 0 (read by rackd with gdos.stderr: auto).
  send("RACK_GDOS", gdos_batch(0, 1, 14));
  send("RACK_GDOS", gdos_batch(2, 1, 0));
  send("RACK_GDOS", gdos_batch(2, 0x7fffffff, 14));
  send("RACK_GDOS", gdos_batch(2, -3, 14));
  send("RACK_GDOS_LISTENER", gdos_listener(0));
  send("RACK_GDOS_LISTENER", gdos_listener(-1));
  // TiMS packets whose size field lies, or that are cut short.
  send("TIMS", tims_packet_claiming(1 << 30, 10));
  send("TIMS", tims_packet_claiming(-1, 10));
  send("TIMS", Bytes(12, 0));
  // Not LCM: too short, wrong magic, channel name without its NUL or too long.
  raw.send_raw(Bytes{0x4c, 0x43});
  Bytes magic(64);
  for (auto& b : magic) b = static_cast<uint8_t>(rng());
  magic[0] = 0x12;
  raw.send_raw(magic);
  Bytes unterminated = {0x4c, 0x43, 0x30, 0x32, 0, 0, 0, 1, 'T', 'I', 'M', 'S'};
  raw.send_raw(unterminated);
  raw.send("C" + std::string(80, 'x'), Bytes(8, 0));
  sent += 4;
  // LCM fragments: the pair that segfaulted the viewer (offsets and sizes that do not
  // fit the message), on every channel a RACK-RT receiver reads.
  for (const std::string ch : {"RACK_GDOS", "TIMS", "TIMS_ANNOUNCE", "RACK_GDOS_LISTENER"}) {
    const auto msg = static_cast<uint32_t>(rng());
    raw.send_fragment(msg, 100, 0, 0, 2, ch, 300);
    raw.send_fragment(msg, 100, 0xFFFFFF00u, 1, 2, "", 300);
    raw.send_fragment(msg, 0xFFFFFFFFu, 70000, 5, 1, "", 100);
    sent += 3;
  }
  return sent;
}

// The last value of `key` on rackd's last status line that starts with `line`
// ("  TiMS/LCM refused: lcm framing 3, lcm fragments 12, ..."); -1 when absent.
long long status_counter(const std::string& out, const std::string& line, const std::string& key) {
  const auto at = out.rfind(line);
  if (at == std::string::npos) return -1;
  const auto end = out.find('\n', at);
  const std::string l = out.substr(at, end == std::string::npos ? std::string::npos : end - at);
  const auto k = l.find(key + " ");
  if (k == std::string::npos) return -1;
  return std::strtoll(l.c_str() + k + key.size() + 1, nullptr, 10);
}

constexpr const char* kHost = R"(host: hostile-test
system: 0
host_id: 0
heap_prefault_mib: 0
gdos: {stderr: auto}
components:
  - name: generator
    class: Generator
    instance: 0
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 70, period_ms: 10}
  - name: monitor
    class: Monitor
    instance: 0
    autostart: true
    data_task: {priority: 50}
    params: {source: generator, source_period_ms: 100, silence_ms: 2000}
)";

class HostileNetTest : public ::testing::Test {
 protected:
  HostileNetTest() : watchdog_(110s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void SetUp() override {
    ASSERT_TRUE(host_.start(host_.write("host.yaml", kHost), {"--status", "1"}));
    rackd_ = &host_.rackd();
  }
  RunResult ctl(std::vector<std::string> args) { return host_.ctl(std::move(args), "1500"); }
  std::optional<Json> status(const std::string& name) {
    const RunResult r = ctl({"status", name, "--json"});
    if (r.exit_code != 0) return std::nullopt;
    return parse_json(r.out);
  }
  static double number(const std::optional<Json>& j, const std::string& key) {
    const Json* v = j ? j->get(key) : nullptr;
    return v != nullptr && v->is_number() ? v->number : -1.0;
  }
  static std::string text(const std::optional<Json>& j, const std::string& key) {
    const Json* v = j ? j->get(key) : nullptr;
    return v != nullptr && v->is_string() ? v->string : "";
  }
  long long refused(const std::string& key) { return status_counter(rackd_->out(), "TiMS/LCM refused:", key); }
  // Waits for a status line printed after now (rackd prints one a second).
  void next_status_line() {
    const std::size_t lines = count_status_lines();
    for (int i = 0; i < 60 && count_status_lines() == lines; ++i) std::this_thread::sleep_for(50ms);
  }
  std::size_t count_status_lines() {
    const std::string out = rackd_->out();
    std::size_t n = 0;
    for (auto at = out.find("TiMS/LCM refused:"); at != std::string::npos; at = out.find("TiMS/LCM refused:", at + 1)) {
      ++n;
    }
    return n;
  }
  // Both components ENABLED, and the generator's cycles since `before` match the time
  // passed at its 10 ms period within a generous tolerance (a shared machine, no
  // PREEMPT_RT: the point is that the flood did not stop or starve it).
  void expect_healthy(const std::optional<Json>& before, std::chrono::steady_clock::time_point since) {
    const auto after = status("generator");
    ASSERT_TRUE(after.has_value()) << rackd_->err();
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
    const double cycles = number(after, "cycles") - number(before, "cycles");
    EXPECT_GT(cycles, 0.5 * elapsed / 0.010) << "cycles " << cycles << " in " << elapsed << " s";
    EXPECT_EQ(text(after, "state"), "ENABLED");
    EXPECT_EQ(text(status("monitor"), "state"), "ENABLED") << rackd_->err();
  }

  Watchdog watchdog_;
  RackdOnBus host_;  // rackd --status 1; stopped (SIGTERM, exit 0) when the test ends
  const TempDir& dir_ = host_.dir();
  const LcmBus& bus_ = host_.bus();
  Process* rackd_ = nullptr;  // once started
};

TEST_F(HostileNetTest, EveryKindOfHostileDatagramIsRefusedCountedAndRackdKeepsItsRate) {
  // A viewer listens: rackd (gdos.stderr: auto) then reads the listener channel too.
  Process viewer({kGdos, "--lcm", bus_.url(), "--json"}, dir_.path(), "gdos");
  ASSERT_TRUE(viewer.wait_for_stderr("gdos: listening", 30s)) << viewer.err();
  const auto before = status("generator");
  ASSERT_TRUE(before.has_value()) << rackd_->err();
  const auto start = std::chrono::steady_clock::now();
  RawLcm raw(bus_.port());
  std::mt19937 rng(17);
  int sent = 0;
  while (std::chrono::steady_clock::now() - start < 3s) {
    for (int i = 0; i < 5; ++i) sent += send_hostile_round(raw, rng);
    std::this_thread::sleep_for(10ms);
  }
  ASSERT_TRUE(rackd_->running()) << rackd_->err();
  expect_healthy(before, start);
  next_status_line();
  // Counted by kind (rackd's status), logged at a bounded rate.
  EXPECT_GT(refused("discovers"), 100) << rackd_->out();
  EXPECT_GT(refused("announcements"), 100) << rackd_->out();
  EXPECT_GT(refused("lcm fragments"), 100) << rackd_->out();
  EXPECT_GT(refused("lcm framing"), 100) << rackd_->out();
  EXPECT_GT(refused("tims packets"), 100) << rackd_->out();
  EXPECT_GT(status_counter(rackd_->out(), "  GDOS:", "listener messages refused"), 10) << rackd_->out();
  // rackd's log goes to the viewer (gdos.stderr: auto): the reasons, at a bounded rate.
  ASSERT_TRUE(viewer.running()) << viewer.err();
  EXPECT_TRUE(eventually([&] { return contains(viewer.out(), "refused an LCM fragment"); })) << viewer.out();
  const std::string log = viewer.out();
  EXPECT_TRUE(contains(log, "string length 0")) << log;
  EXPECT_TRUE(contains(log, "more like it suppressed")) << log;
  std::size_t lines = 0;
  for (auto at = log.find("TiMS/LCM: "); at != std::string::npos; at = log.find("TiMS/LCM: ", at + 1)) ++lines;
  EXPECT_LT(lines, 200u) << sent << " hostile datagrams made " << lines << " log lines";
  // The viewer is still up, and still shows what rackd logs (an OFF/ON of the
  // generator after the flood: its "ON" record), not the forged batches.
  ASSERT_TRUE(viewer.running()) << viewer.err();
  EXPECT_EQ(ctl({"off", "generator"}).exit_code, 0);
  EXPECT_EQ(ctl({"on", "generator"}).exit_code, 0);
  EXPECT_TRUE(eventually([&] { return contains(viewer.out(), "ON: ENABLED"); })) << viewer.out() << viewer.err();
  EXPECT_FALSE(contains(viewer.out(), "forged record")) << viewer.out();
  viewer.signal(SIGINT);
  EXPECT_EQ(viewer.wait_exit(10s), std::optional<int>(0)) << viewer.err();
  const std::string verr = viewer.err();
  EXPECT_TRUE(contains(verr, "LCM fragment of")) << verr;
  EXPECT_TRUE(contains(verr, "dropped a malformed batch")) << verr;
  EXPECT_FALSE(contains(verr, " 0 LCM fragment(s)")) << verr;
  EXPECT_FALSE(contains(verr, " 0 malformed batch(es)")) << verr;
  EXPECT_FALSE(contains(verr, " 0 announcement(s) that did not decode")) << verr;
}

TEST_F(HostileNetTest, RackctlWorksDuringAFloodOfHostileDatagrams) {
  RawLcm raw(bus_.port());
  std::atomic<bool> stop{false};
  std::thread flood([&] {
    std::mt19937 rng(4);
    while (!stop.load()) {
      (void)send_hostile_round(raw, rng);
      std::this_thread::sleep_for(5ms);
    }
  });
  const RunResult list = ctl({"list"});
  const RunResult hosts = ctl({"hosts"});
  stop.store(true);
  flood.join();
  EXPECT_EQ(list.exit_code, 0) << list.describe();
  EXPECT_TRUE(contains(list.out, "generator") && contains(list.out, "ENABLED")) << list.describe();
  EXPECT_TRUE(contains(list.out, "monitor")) << list.describe();
  EXPECT_EQ(hosts.exit_code, 0) << hosts.describe();
  EXPECT_TRUE(contains(hosts.out, "hostile-test")) << hosts.describe();
  EXPECT_TRUE(rackd_->running());
}

TEST_F(HostileNetTest, DiscoverFloodIsAnsweredAtABoundedRateAndCounted) {
  next_status_line();
  const long long answered_before = refused("answered");
  const auto before = status("generator");
  ASSERT_TRUE(before.has_value());
  RawLcm raw(bus_.port());
  const auto start = std::chrono::steady_clock::now();
  int sent = 0;
  while (std::chrono::steady_clock::now() - start < 2s) {
    for (int i = 0; i < 20; ++i) raw.send("TIMS_DISCOVER", good_discover(0x40000 + sent++));
    std::this_thread::sleep_for(5ms);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  expect_healthy(before, start);
  next_status_line();
  const long long answered = refused("answered") - answered_before;
  const long long coalesced = refused("coalesced");
  // At most one answer per 100 ms on the one network (plus the rackctl calls' own).
  EXPECT_LE(answered, static_cast<long long>(seconds * 10) + 10) << rackd_->out();
  EXPECT_GT(answered, 0) << rackd_->out();
  // Most requests shared an answer (some may be lost in a full socket buffer on a busy
  // machine: the bound is loose).
  EXPECT_GT(coalesced, sent / 10) << sent << " sent\n" << rackd_->out();
  // And discovery still works: a tool's request is answered.
  const RunResult list = ctl({"list"});
  EXPECT_TRUE(contains(list.out, "generator")) << list.describe();
}

TEST_F(HostileNetTest, FloodOfMadeUpHostsIsBoundedAndCounted) {
  RawLcm raw(bus_.port());
  const auto before = status("generator");
  ASSERT_TRUE(before.has_value());
  const auto start = std::chrono::steady_clock::now();
  // 400 hosts that do not exist, each its own system and host id (not a restart).
  for (int i = 0; i < 400; ++i) {
    raw.send("TIMS_ANNOUNCE", good_announce(0x70000 + i, 1 + i / 256, i % 256));
    if (i % 50 == 49) std::this_thread::sleep_for(5ms);
  }
  next_status_line();
  EXPECT_GT(refused("hosts over the limit"), 0) << rackd_->out();
  EXPECT_TRUE(contains(rackd_->err(), "hosts known already")) << rackd_->err();
  expect_healthy(before, start);
}

}  // namespace
}  // namespace rack::test
