// No allocation after initialisation on the message path.
//
// This binary replaces the global allocator (operator new/delete and glibc's malloc
// family, forwarding to glibc's __libc_* entry points) with versions that count every
// allocation made, by any thread, while counting is switched on. Each replacement
// also calls the mode-switch detector's hook (modeswitch::detail::on_heap_call), as
// any program that replaces the allocator must to keep ALLOC detection working. Each test sets up
// and warms up its path, then switches counting on around the measured loop only:
// the count must stay 0. Alone in its binary because the replacement is global.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <functional>
#include <new>
#include <string>
#include <thread>

#include "rack/components/class_ids.h"
#include "rack/core/class_description.h"
#include "rack/core/gdos.h"
#include "probe/probe_types.h"
#include "pilot/pilot_types.h"
#include "rack/interfaces/demo.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"
#include "rack/rt/modeswitch.h"
#include "rack/rt/trace.h"
#include "rack/tims/trusted_sources.h"
#include "test_support.h"

// ---- the counting allocator ----------------------------------------------------

namespace {
// Relaxed: a flag and a statistic; the measured loop is bracketed on one thread and
// the count is read after the threads involved have synchronised through mailboxes.
std::atomic<bool> g_counting{false};
std::atomic<uint64_t> g_allocations{0};
}  // namespace

void rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall call, std::size_t size) noexcept {
  rack::rt::modeswitch::detail::on_heap_call(call, size);
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
}
void rack_test_note_free() noexcept {
  rack::rt::modeswitch::detail::on_heap_call(rack::rt::modeswitch::detail::HeapCall::kFree, 0);
}

#include "counting_allocator.h"

// ---- tests ---------------------------------------------------------------------

namespace rack {
namespace {

using tims::Address;
using tims::ConstBuffer;
using tims::Mailbox;
using tims::RecvStatus;
using tims::SendStatus;
namespace msg = tims::msg;

// Counts allocations (all threads) from construction to stop().
class AllocationCounter {
 public:
  AllocationCounter() {
    g_allocations.store(0, std::memory_order_relaxed);
    g_counting.store(true, std::memory_order_seq_cst);
  }
  ~AllocationCounter() { g_counting.store(false, std::memory_order_seq_cst); }
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  uint64_t stop() {
    g_counting.store(false, std::memory_order_seq_cst);
    return g_allocations.load(std::memory_order_relaxed);
  }
};

void* volatile g_sink = nullptr;  // keeps the compiler from eliding test allocations

class NoAllocationTest : public ::testing::Test {
 protected:
  static constexpr int kWarmUp = 20;
  static constexpr int kRounds = 500;
  static constexpr Address kA = Address::make(0, tims::classes::kTool, 1, 1);
  static constexpr Address kB = Address::make(0, tims::classes::kTool, 2, 1);

  // `round(i)` does one round of the work and says whether it went right: kWarmUp
  // rounds first (each must), then kRounds under an AllocationCounter, in which every
  // round goes right and nothing allocates.
  static void expect_rounds_allocate_nothing(const std::function<bool(int)>& round) {
    for (int i = 0; i < kWarmUp; ++i) ASSERT_TRUE(round(i)) << "warm-up round " << i;
    int failures = 0;
    AllocationCounter counter;
    for (int i = 0; i < kRounds; ++i) failures += round(i) ? 0 : 1;
    const uint64_t allocations = counter.stop();
    EXPECT_EQ(failures, 0);
    EXPECT_EQ(allocations, 0u);
  }
};

TEST_F(NoAllocationTest, CounterSeesAllocations) {
  // The check must be able to fail: every kind of allocation is seen.
  {
    AllocationCounter c;
    g_sink = std::malloc(16);
    std::free(g_sink);
    EXPECT_EQ(c.stop(), 1u);
  }
  {
    AllocationCounter c;
    g_sink = new int(3);
    delete static_cast<int*>(g_sink);
    EXPECT_EQ(c.stop(), 1u);
  }
  {
    AllocationCounter c;
    std::string s(200, 'x');  // allocates inside libstdc++
    g_sink = s.data();
    EXPECT_GE(c.stop(), 1u);
  }
  {
    AllocationCounter c;
    std::thread t([] { g_sink = std::malloc(8); });
    t.join();
    std::free(g_sink);
    EXPECT_GE(c.stop(), 2u);  // the thread's start and its malloc
  }
  {
    AllocationCounter c;
    c.stop();
    g_sink = std::malloc(8);  // after stop: not counted
    std::free(g_sink);
    EXPECT_EQ(g_allocations.load(), 0u);
  }
}

TEST_F(NoAllocationTest, MailboxSendReceivePeek) {
  Mailbox m(kA, 8, 256);
  alignas(8) std::array<std::byte, 256> buf{};
  const test::Tag tag{1, 0};
  auto round = [&](int i) {
    const auto h = test::tag_header(kA, kB, static_cast<uint8_t>(i % 4));
    if (!delivered(m.try_send(h, {tims::buffer_of(tag)}))) return false;
    if (!delivered(m.try_send(h, {tims::buffer_of(tag)}))) return false;
    if (m.receive(buf, Mailbox::kNonBlocking).status != RecvStatus::kOk) return false;
    const auto p = m.peek(Mailbox::kNonBlocking);
    if (p.status != RecvStatus::kOk) return false;
    m.peek_end();
    // Full mailbox: drop policy and refusals allocate nothing either.
    for (int k = 0; k < 10; ++k) (void)m.try_send(h, {tims::buffer_of(tag)});
    while (m.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk) {
    }
    return m.receive(buf, 1000).status == RecvStatus::kTimeout;  // timed wait path
  };
  expect_rounds_allocate_nothing(round);
}

TEST_F(NoAllocationTest, RouterSend) {
  tims::Router router(0);
  Mailbox a(kA, 8, 256), b(kB, 8, 256);
  router.add(a);
  router.add(b);
  alignas(8) std::array<std::byte, 256> buf{};
  const test::Tag tag{2, 0};
  auto round = [&](int) {
    if (router.send(test::tag_header(kB, kA, 1), {tims::buffer_of(tag)}) != SendStatus::kOk) return false;
    if (b.receive(buf, Mailbox::kNonBlocking).status != RecvStatus::kOk) return false;
    // A request to nobody: answered NOT_AVAILABLE into a.
    const auto req = tims::make_header(Address::make(0, class_ids::kLadar, 9), kA, msg::kOn, 1, 1, 0);
    if (router.send(req, std::span<const ConstBuffer>{}) != SendStatus::kNotAvailable) return false;
    return a.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk;
  };
  expect_rounds_allocate_nothing(round);
  router.remove(kA);
  router.remove(kB);
}

TEST_F(NoAllocationTest, RouterSendThroughAccessControl) {
  // The access check in the send path, allowed and refused (rate, type), with the
  // ERROR reply of a refused request: no allocation.
  tims::AccessConfig config;
  tims::AccessRuleConfig r;
  r.name = "limited";
  r.to.push_back({kB.component().raw(), 0xFFFFFF00u});
  r.any_type = false;
  r.types.set(static_cast<std::size_t>(msg::kOn + 128));
  r.rate = 1;
  r.burst = 1;
  config.rules.push_back(r);
  tims::AccessControl access(config);
  tims::Router router(0);
  Mailbox a(kA, 8, 256), b(kB, 8, 256);
  router.add(a);
  router.add(b);
  router.set_access(&access);
  alignas(8) std::array<std::byte, 256> buf{};
  int answers = 0;
  auto round = [&](int) {
    // ON: the first per second passes, the rest hit the rate limit; OFF: wrong type.
    for (const int8_t type : {msg::kOn, msg::kOff}) {
      const auto h = tims::make_header(kB, kA, type, 1, 1, 0);
      (void)router.send(h, std::span<const ConstBuffer>{});
    }
    while (b.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk) {
    }
    // ERROR answers (at most AccessControl::kRepliesPerSecond per second).
    while (a.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk) ++answers;
    return true;
  };
  expect_rounds_allocate_nothing(round);
  EXPECT_GT(access.counters()[0].denied_rate, 0u);
  EXPECT_EQ(access.counters()[0].denied_type, static_cast<uint64_t>(kWarmUp + kRounds));
  EXPECT_GT(answers, 0);
  router.set_access(nullptr);
  router.remove(kA);
  router.remove(kB);
}

TEST_F(NoAllocationTest, RouterRefusesWhatADataMailboxDoesNotTrust) {
  // A consumer's data mailbox (TrustedSources): a trusted sample passes, a forged one
  // and a request are refused, the request answered NOT_AVAILABLE: no allocation.
  tims::Router router(0);
  Mailbox a(kA, 8, 256);
  const Address producer = Address::make(0, class_ids::kLadar, 1);
  Mailbox input(kB.with_mailbox(3), 8, 256);
  tims::TrustedSources trusted(kB);
  input.set_trusted_sources(&trusted);
  router.add(a);
  router.add(input);
  ASSERT_TRUE(trusted.trust(producer, rt::monotonic_ns()));
  alignas(8) std::array<std::byte, 256> buf{};
  const test::Tag tag{3, 0};
  auto round = [&](int) {
    if (router.send(test::tag_header(input.address(), producer, 1), {tims::buffer_of(tag)}) != SendStatus::kOk) {
      return false;
    }
    if (router.send(test::tag_header(input.address(), kA, 1), {tims::buffer_of(tag)}) != SendStatus::kDenied) {
      return false;
    }
    const auto req = tims::make_header(input.address(), kA, msg::kGetStatus, 1, 1, 0);
    if (router.send(req, std::span<const ConstBuffer>{}) != SendStatus::kDenied) return false;
    while (a.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk) {
    }
    return input.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk;
  };
  expect_rounds_allocate_nothing(round);
  EXPECT_EQ(trusted.counters().forged, static_cast<uint64_t>(kWarmUp + kRounds));
  router.remove(kA);
  router.remove(input.address());
}

TEST_F(NoAllocationTest, SubscriptionLeasesRenewAndExpire) {
  // A consumer renewing its lease from its data task (every 50 ms) and a listener
  // that never renews, dropped with an ERROR when its lease runs out: no allocation.
  test::Watchdog dog;
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    data_task: {period_ms: 5, lease_ms: 200}
  - name: mon
    class: Monitor
    instance: 1
    autostart: true
    params: {source: gen, source_period_ms: 5}
)");
  const Address gen = host.address_of("gen");
  const Address mon = host.address_of("mon");
  ASSERT_TRUE(host.wait_status(mon, msg::kEnabled));
  wire::ContDataRequest cont;
  cont.mailbox = host.data_mailbox().address().raw();
  ASSERT_EQ(host.call_with(gen, msg::kGetContData, cont).type, msg::kContData);
  const uint64_t mon_errors = host.stats(mon).errors;
  const uint64_t expired = host.stats(gen).listeners_expired;
  host.executor().flush_log();
  uint64_t allocations = 0;
  {
    AllocationCounter counter;
    std::this_thread::sleep_for(std::chrono::milliseconds(600));  // 3 leases, 12 renewals
    allocations = counter.stop();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_GT(host.stats(gen).listeners_expired, expired) << "the tool's listener expired meanwhile";
  EXPECT_EQ(host.stats(mon).errors, mon_errors) << "the monitor renewed in time";
  EXPECT_EQ(host.stats(gen).listeners, 1u);
}

TEST_F(NoAllocationTest, EndpointCallRoundTrip) {
  test::Watchdog dog;
  tims::Router router(0);
  Mailbox client_box(kA, 8, 256), server_box(kB, 8, 256);
  router.add(client_box);
  router.add(server_box);
  std::atomic<bool> stop{false};
  std::thread server([&] {
    tims::Endpoint ep(router, server_box, 5);
    alignas(8) std::array<std::byte, 256> b{};
    while (!stop.load(std::memory_order_acquire)) {
      const auto r = server_box.receive(b, 10 * rt::kNsPerMs);
      if (r.status != RecvStatus::kOk) continue;
      const ConstBuffer body{b.data() + sizeof(tims::MessageHeader), r.length - sizeof(tims::MessageHeader)};
      (void)ep.reply(r.header, msg::kOk, std::span<const ConstBuffer>(&body, 1));
    }
  });
  tims::Endpoint client(router, client_box, 5);
  alignas(8) std::array<std::byte, 256> buf{};
  const uint64_t word = 42;
  auto round = [&] {
    const auto r = client.call(kB, 21, word, buf, test::kCallTimeoutNs);
    return r.ok() && r.body.size() == sizeof word;
  };
  for (int i = 0; i < kWarmUp; ++i) ASSERT_TRUE(round());
  int failures = 0;
  {
    AllocationCounter counter;
    for (int i = 0; i < kRounds; ++i) failures += round() ? 0 : 1;
    const uint64_t allocations = counter.stop();
    EXPECT_EQ(allocations, 0u);
  }
  stop.store(true, std::memory_order_release);
  server.join();
  EXPECT_EQ(failures, 0);
  router.remove(kA);
  router.remove(kB);
}

TEST_F(NoAllocationTest, RpcToARunningExecutorComponent) {
  test::Watchdog dog;
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: probe
    class: Probe
    instance: 1
    data_task: {period_ms: 5, ring: 64}
  - name: gen
    class: Generator
    instance: 1
    data_task: {period_ms: 5}
)");
  const Address probe = host.address_of("probe");
  const Address gen = host.address_of("gen");
  ASSERT_EQ(host.call(probe, msg::kOn).type, msg::kOk);
  ASSERT_EQ(host.call(gen, msg::kOn).type, msg::kOk);
  // A stream of generator samples into the tool's data mailbox: the producer's
  // publish path runs during the measurement too.
  wire::ContDataRequest cont;
  cont.mailbox = host.data_mailbox().address().raw();
  ASSERT_EQ(host.call_with(gen, msg::kGetContData, cont).type, msg::kContData);
  // Both producers have a sample (the warm-up asks both for their newest; on a loaded
  // machine the generator's first period may not have passed yet).
  ASSERT_TRUE(test::eventually([&] {
    wire::SampleHeader h;
    interfaces::ProbeData d;
    interfaces::GeneratorData g;
    return host.get_data(probe, h, d) && host.get_data(gen, h, g);
  }));
  // The generator's first sample too: GET_DATA on an empty ring answers ERROR, which a
  // loaded machine (its first period late) turned into a failure of the warm-up below.
  ASSERT_TRUE(test::eventually([&] {
    wire::SampleHeader h;
    interfaces::GeneratorData d;
    return host.get_data(gen, h, d);
  }));
  // The generator too: GET_DATA on an empty ring is (rightly) an ERROR.
  ASSERT_TRUE(test::eventually([&] {
    wire::SampleHeader h;
    interfaces::GeneratorData d;
    return host.get_data(gen, h, d);
  }));

  tims::Endpoint& ep = host.endpoint();
  alignas(8) std::array<std::byte, 4096> buf{};
  alignas(8) std::array<std::byte, 1024> data{};
  wire::ParamName pname;
  wire::copy_text(pname.name, "label");
  uint64_t bad = 0, streamed = 0;
  const ClassPageRequest class_page{};
  auto round = [&] {
    auto r = ep.call(probe, msg::kGetStatus, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kEnabled ? 0 : 1;
    r = ep.call(probe, msg::kGetData, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kData ? 0 : 1;
    r = ep.call(gen, msg::kGetData, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kData ? 0 : 1;
    r = ep.call(probe, msg::kGetParam, pname, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kParam ? 0 : 1;
    r = ep.call(probe, msg::kGetStats, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kStats ? 0 : 1;
    // The periodic generator's histogram, added up into GET_LATENCY's buckets.
    r = ep.call(gen, msg::kGetLatency, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kLatency ? 0 : 1;
    // Who subscribes to the generator: the tool's data mailbox (GET_LISTENERS).
    r = ep.call(gen, msg::kGetListeners, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kListeners ? 0 : 1;
    // How its tasks run (GET_TASKS: the GDOS thread's last kernel reading, the networks).
    r = ep.call(gen, msg::kGetTasks, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kTasks ? 0 : 1;
    // The class description's first page (encoded before the tasks started).
    r = ep.call(gen, msg::kGetClass, class_page, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kClass ? 0 : 1;
    r = ep.call(Address::make(0, class_ids::kLadar, 7), msg::kGetStatus, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kNotAvailable ? 0 : 1;
    while (host.data_mailbox().receive(data, Mailbox::kNonBlocking).status == RecvStatus::kOk) ++streamed;
  };
  for (int i = 0; i < kWarmUp; ++i) round();
  ASSERT_EQ(bad, 0u);
  // The start-up and ON log records are formatted now, not during the measurement
  // (the GDOS thread is not RT and may allocate while its buffers grow).
  host.executor().flush_log();
  streamed = 0;
  uint64_t allocations = 0;
  {
    // At least 200 rounds, and on until a few streamed samples arrived (the producer's
    // period is 5 ms; 200 rounds can be quicker than that). Bounded by the watchdog.
    AllocationCounter counter;
    for (int i = 0; i < 200 || (streamed < 3 && i < 200000); ++i) round();
    allocations = counter.stop();
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_GT(streamed, 0u) << "the producer published during the measurement";
  EXPECT_EQ(allocations, 0u);
}

// SET_PARAM with the class's rules (Component::check_parameters) and the Spec's:
// accepted and refused values, a start-only parameter, all in the command task
// without one allocation.
TEST_F(NoAllocationTest, SetParamChecksTheClassRules) {
  test::Watchdog dog;
  // Every SET_PARAM is logged at info level (700 lines in the counted window): a ring
  // large enough that none is dropped, since the GDOS thread (not RT) allocates the
  // "records dropped" line and this test counts the allocations of every thread.
  test::HostUnderTest host(R"y(system: 0
lcm: false
heap_prefault_mib: 0
gdos: {ring: 4096}
components:
  - name: pilot
    class: Pilot
    data_task: {period_ms: 50}
    params: {chassis: "Chassis(0/9)", position: "Position(0/9)", scan2d: "Scan2D(0/9)"}
  - name: path
    class: Path
    data_task: {period_ms: 200}
    params: {waypoints: "0,0; 4,0; 4,3"}
)y");
  const Address pilot = host.address_of("pilot");
  const Address path = host.address_of("path");
  tims::Endpoint& ep = host.endpoint();
  alignas(8) std::array<std::byte, 4096> buf{};
  const auto record = [](const char* name, const char* text) {
    wire::ParamRecord r;
    wire::copy_text(r.name, name);
    r.kind = static_cast<uint8_t>(wire::ParamKind::kString);
    wire::copy_text(r.string_value, text);
    return r;
  };
  const std::array<std::pair<wire::ParamRecord, int8_t>, 4> pilot_sets{{
      {record("destination", "2.5,1"), msg::kOk},
      {record("destination", "two,one"), msg::kError},
      {record("mode", "fly"), msg::kError},
      {record("destination", ""), msg::kOk},
  }};
  const std::array<std::pair<wire::ParamRecord, int8_t>, 3> path_sets{{
      {record("waypoints", "0,0; 2,0; 2,2"), msg::kOk},
      {record("waypoints", "0,0; x"), msg::kError},
      {record("waypoints", "0,0; 4,0; 4,3"), msg::kOk},
  }};
  uint64_t bad = 0;
  auto round = [&] {
    for (const auto& [r, expected] : pilot_sets) {
      const auto a = ep.call(pilot, msg::kSetParam, r, buf, test::kCallTimeoutNs);
      bad += a.status == tims::CallStatus::kOk && a.reply.type == expected ? 0 : 1;
    }
    for (const auto& [r, expected] : path_sets) {
      const auto a = ep.call(path, msg::kSetParam, r, buf, test::kCallTimeoutNs);
      bad += a.status == tims::CallStatus::kOk && a.reply.type == expected ? 0 : 1;
    }
  };
  for (int i = 0; i < kWarmUp; ++i) round();
  ASSERT_EQ(bad, 0u);
  host.executor().flush_log();
  uint64_t allocations = 0;
  {
    AllocationCounter counter;
    for (int i = 0; i < 100; ++i) round();
    allocations = counter.stop();
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(allocations, 0u);
}

// The simulated robot and navigation stack (issue 6) in steady state: every task of
// ChassisSim, LadarSim (ray casting), Odometry, Scan2D (with odometry look-ups by
// time), Position, Path and Pilot (MOVEs every cycle), plus UPDATE, SET_DESTINATION,
// FOLLOW_PATH and MAKE commands, without one allocation.
TEST_F(NoAllocationTest, SimulatedRobotDrivingAndCommands) {
  test::Watchdog dog(std::chrono::seconds(60));
  const std::string map = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: chassis
    class: ChassisSim
    instance: 0
    data_task: {priority: 45, period_ms: 10, ring: 200}
    params: {map: ")" + map +
                           R"(", initial_x: 3.0, initial_y: 7.0}
  - name: odometry
    class: Odometry
    instance: 0
    data_task: {priority: 44, ring: 500}
    params: {chassis: chassis}
  - name: position
    class: Position
    instance: 0
    data_task: {priority: 43, ring: 100}
    params: {odometry: odometry, initial_x: 3.0, initial_y: 7.0}
  - name: ladar
    class: LadarSim
    instance: 0
    data_task: {priority: 42, period_ms: 40, ring: 10}
    params: {chassis: chassis, map: ")" +
                           map + R"(", mount_x: 0.2}
  - name: scan2d
    class: Scan2D
    instance: 0
    data_task: {priority: 41, ring: 10}
    params: {ladar: ladar, odometry: odometry, mount_x: 0.2, median: 3}
  - name: path
    class: Path
    instance: 0
    data_task: {priority: 20, period_ms: 20, ring: 4}
    params: {waypoints: "3,7; 12,7.5; 21,7; 22,8; 21,9; 12,8.5; 3,9; 2,8", closed: true}
  - name: pilot
    class: Pilot
    instance: 0
    data_task: {priority: 40, period_ms: 50}
    params: {chassis: chassis, position: position, scan2d: scan2d, path: path}
)");
  const Address pilot = host.address_of("pilot");
  const Address position = host.address_of("position");
  const Address path = host.address_of("path");
  ASSERT_EQ(host.call(pilot, msg::kOn).type, msg::kOk);
  ASSERT_TRUE(test::eventually([&] {
    wire::SampleHeader h;
    interfaces::PilotData d;
    return host.get_data(pilot, h, d) && d.status == static_cast<uint8_t>(interfaces::PilotStatus::kDriving);
  }));
  tims::Endpoint& ep = host.endpoint();
  alignas(8) std::array<std::byte, 32 * 1024> buf{};
  uint64_t bad = 0;
  int64_t last_odometry_ns = 0;
  auto round = [&](int i) {
    // An UPDATE for a moment 100 ms ago (as MCL sends), at the pose Position had then.
    auto r = ep.call(position, msg::kGetData, buf, test::kCallTimeoutNs);
    wire::SampleHeader sh;
    interfaces::PositionData p;
    if (r.status == tims::CallStatus::kOk && r.reply.type == msg::kData && read_sample(r.reply, r.body, sh, p)) {
      interfaces::PositionUpdate u;
      u.time_ns = sh.time_ns - 100 * rt::kNsPerMs;
      u.x = p.x;
      u.y = p.y;
      u.phi = p.phi;
      u.var_x = u.var_y = 0.01;
      u.var_phi = 0.001;
      r = ep.call(position, interfaces::kPositionUpdate, u, buf, test::kCallTimeoutNs);
      bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kOk ? 0 : 1;
      last_odometry_ns = sh.time_ns;
    } else {
      ++bad;
    }
    if (i % 5 == 0) {
      interfaces::PilotDestination d{12.0, 8.0};
      r = ep.call(pilot, interfaces::kPilotSetDestination, d, buf, test::kCallTimeoutNs);
      bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kOk ? 0 : 1;
    }
    if (i % 5 == 2) {
      r = ep.call(pilot, interfaces::kPilotFollowPath, buf, test::kCallTimeoutNs);
      bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kOk ? 0 : 1;
      r = ep.call(path, interfaces::kPathMake, buf, test::kCallTimeoutNs);
      bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kOk ? 0 : 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  };
  // The odometry's ring must reach back further than the UPDATEs' 100 ms.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  for (int i = 0; i < 10; ++i) round(i);
  ASSERT_EQ(bad, 0u);
  uint64_t allocations = 0;
  {
    AllocationCounter counter;  // every thread: the component tasks run meanwhile
    for (int i = 0; i < 60; ++i) round(i);
    allocations = counter.stop();
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_GT(last_odometry_ns, 0);
  wire::SampleHeader h;
  interfaces::PilotData d;
  ASSERT_TRUE(host.get_data(pilot, h, d));
  EXPECT_EQ(d.moves_refused, 0u);
  EXPECT_EQ(allocations, 0u);
}

TEST_F(NoAllocationTest, GdosLogCallsInAnRtTask) {
  // The RT side of GDOS: a task with a bound ring logs records of every argument
  // kind, with the ring filling up (drops) in between; nothing allocates.
  test::Watchdog dog;
  gdos::LogRing ring(16, "test task");
  gdos::LogSource src(Address::make(0, class_ids::kLadar, 1), "ladar", gdos::Level::kInfo);
  const Address dest = Address::make(0, class_ids::kPosition, 2);
  const std::string name = "a std::string longer than the small-string buffer";
  uint64_t allocations = ~uint64_t{0};
  uint64_t written = 0;
  std::thread task([&] {
    (void)rt::set_current_thread_priority(50);  // SCHED_FIFO when allowed (the test runs either way)
    gdos::bind_thread_ring(&ring);
    auto round = [&](int i) {
      gdos::log(src, gdos::Level::kInfo, "cycle %d: %f m at %s (%s), %zu points, %p", i, 0.25 * i, dest, "scan",
                static_cast<std::size_t>(i) * 3, static_cast<const void*>(&ring));
      gdos::log(src, gdos::Level::kWarning, "%s %.*s %lld %Lg %c", name, 3, std::string_view("abcdef"),
                static_cast<long long>(i), static_cast<long double>(i), 'x');
      gdos::log(src, gdos::Level::kDetail, "filtered out by the level %d", i);
      gdos::log(src, gdos::Level::kPrint, "print");
      if (i % 8 == 7) {
        // The consumer side (here: the same thread, so SPSC holds) empties the ring
        // only every 8th round: the rounds in between overflow it.
        while (ring.peek() != nullptr) ring.pop();
      }
    };
    for (int i = 0; i < kWarmUp; ++i) round(i);
    AllocationCounter counter;
    for (int i = 0; i < kRounds; ++i) round(i);
    allocations = counter.stop();
    written = ring.written();
  });
  task.join();
  EXPECT_EQ(allocations, 0u);
  EXPECT_GT(ring.dropped(), 0u) << "the drop path ran too";
  EXPECT_GT(written, static_cast<uint64_t>(kRounds)) << "records were written";
}

TEST_F(NoAllocationTest, TraceHooksWithTracingOnAndOff) {
  // A task with its trace ring bound: cycle hooks and the message hand-offs of the
  // router and mailbox record into the preallocated ring, on and off, full or not.
  tims::Router router(0);
  Mailbox a(kA, 8, 256), b(kB, 8, 256);
  router.add(a);
  router.add(b);
  rt::trace::Ring ring(64);  // small: the rounds overflow it (the drop path runs too)
  uint64_t allocations = 0;
  int failures = 0;
  std::thread task([&] {
    rt::trace::bind_thread_ring(&ring);
    alignas(8) std::array<std::byte, 256> buf{};
    const test::Tag tag{3, 0};
    auto round = [&](int i) {
      ring.set_enabled(i % 3 != 0);
      rt::trace::record(rt::trace::Kind::kWake, i);
      rt::trace::record(rt::trace::Kind::kCycleStart);
      if (router.send(test::tag_header(kB, kA, 1), {tims::buffer_of(tag)}) != SendStatus::kOk) ++failures;
      if (b.receive(buf, Mailbox::kNonBlocking).status != RecvStatus::kOk) ++failures;
      rt::trace::record(rt::trace::Kind::kCycleEnd);
      rt::trace::record(rt::trace::Kind::kOverrun, 1);
    };
    for (int i = 0; i < kWarmUp; ++i) round(i);
    AllocationCounter counter;
    for (int i = 0; i < kRounds; ++i) round(i);
    allocations = counter.stop();
    rt::trace::bind_thread_ring(nullptr);
  });
  task.join();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(allocations, 0u);
  EXPECT_GT(ring.dropped(), 0u) << "the drop path ran too";
  EXPECT_EQ(ring.pushed(), ring.capacity()) << "the ring filled, nobody drained it";
  router.remove(kA);
  router.remove(kB);
}

}  // namespace
}  // namespace rack
