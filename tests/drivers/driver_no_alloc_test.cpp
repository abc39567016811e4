// No allocation on the drivers' real-time I/O paths: CanPort send/receive, SerialPort
// read/write, TcpSensorLink read, and the NMEA, SCIP and CoLa-A parsers.
//
// The counting allocator of tests/unit/counting_allocator.h, counting only on
// the thread that switched counting on (thread_local): the simulators and the link
// thread on the other side allocate freely, as non-RT code may. Each test opens and
// warms up its path, then counts around the measured loop only: the count must stay 0.
// Alone in its binary because the replacement is global.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>
#include <thread>

#include "../unit/test_support.h"

// ---- the counting allocator ----------------------------------------------------

namespace {
// Per thread: only the measured (RT-like) thread counts.
thread_local bool g_counting = false;
thread_local uint64_t g_allocations = 0;
}  // namespace

void rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall, std::size_t) noexcept {
  if (g_counting) ++g_allocations;
}
void rack_test_note_free() noexcept {}

#include "../unit/counting_allocator.h"

// ---- tests ---------------------------------------------------------------------

#include <sys/socket.h>
#include <unistd.h>

#include "rack/devices/can_port.h"
#include "rack/devices/canopen.h"
#include "rack/devices/cola.h"
#include "rack/devices/nmea.h"
#include "rack/devices/scip.h"
#include "rack/devices/serial_port.h"
#include "rack/devices/tcp_sensor_link.h"
#include "rack/sims/cia402_sim.h"
#include "rack/sims/nmea_gps_sim.h"
#include "rack/sims/sick_lms1xx_sim.h"

namespace rack::devices {
namespace {

class Counting {
 public:
  Counting() {
    g_allocations = 0;
    g_counting = true;
  }
  ~Counting() { g_counting = false; }
  uint64_t stop() {
    g_counting = false;
    return g_allocations;
  }
};

TEST(DriverNoAllocTest, TheCounterSeesAllocationsOnThisThreadOnly) {
  std::atomic<bool> go{false};
  std::thread other([&] {
    while (!go.load()) std::this_thread::yield();
    auto q = std::make_unique<int>(2);  // another thread: not counted
  });
  Counting c;
  auto p = std::make_unique<int>(1);
  go.store(true);
  other.join();
  EXPECT_EQ(c.stop(), 1U) << "the make_unique on this thread";
}

TEST(DriverNoAllocTest, CanPortCycleAgainstTheDriveSimulator) {
  test::Watchdog w;
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
  sims::Cia402DriveSim sim({});
  sim.attach(sv[1]);
  sim.start();
  CanPort port;
  port.adopt(sv[0]);
  const can_filter filters[] = {{canopen::kTpdo1, 0x780}, {canopen::kTpdo2, 0x780}, {canopen::kHeartbeat, 0x780}};
  std::string error;
  ASSERT_TRUE(port.set_filters(filters, error));
  ASSERT_EQ(port.send(canopen::nmt(canopen::kNmtStart, 0)).status, IoStatus::kOk);
  uint64_t frames = 0;
  Counting c;
  for (int cycle = 0; cycle < 200; ++cycle) {  // a ChassisCan cycle: RPDOs, SYNC, TPDOs
    (void)port.send(canopen::rpdo1(1, canopen::kCwEnableOperation, 100));
    (void)port.send(canopen::rpdo1(2, canopen::kCwEnableOperation, 100));
    (void)port.send(canopen::sync());
    can_frame f{};
    while (port.receive(f, 2 * rt::kNsPerMs).status == IoStatus::kOk) ++frames;
  }
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_GT(frames, 200U) << "the cycle really ran";
  sim.stop();
}

// ChassisCan opens its bus in on() (its command task) and retries every second while
// the bus is missing: the failing opens allocate nothing and say what is missing.
TEST(DriverNoAllocTest, CanPortOpenFailuresAllocateNothing) {
  test::Watchdog w;
  char tmpl[] = "/tmp/rack-can-open-XXXXXX";
  const int tmp_fd = ::mkstemp(tmpl);
  ASSERT_GE(tmp_fd, 0);
  ::close(tmp_fd);
  const std::string regular = tmpl;  // a regular file where a socket is expected
  const std::string unix_regular = "unix:" + regular;
  CanPort port;
  CanError missing, not_socket, no_interface;
  Counting c;
  const bool a = port.open("unix:/nonexistent/rack-chassis.can", missing);
  const bool b = port.open(unix_regular.c_str(), not_socket);
  const bool d = port.open("rackcan9", no_interface);
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_FALSE(a);
  EXPECT_FALSE(b);
  EXPECT_FALSE(d);
  EXPECT_STREQ(missing.text, "/nonexistent/rack-chassis.can: connect: No such file or directory");
  EXPECT_NE(std::string(not_socket.text).find("not a socket"), std::string::npos) << not_socket.text;
  EXPECT_NE(std::string(no_interface.text).find("rackcan9: "), std::string::npos) << no_interface.text;
  EXPECT_FALSE(port.is_open());
  ::unlink(tmpl);
}

TEST(DriverNoAllocTest, SerialReadAndNmeaParsing) {
  test::Watchdog w;
  sims::NmeaGpsSim::Config cfg;
  cfg.period_ns = 10 * rt::kNsPerMs;
  sims::NmeaGpsSim sim(cfg);
  sim.start();
  SerialPort port;
  std::string error;
  ASSERT_TRUE(port.open(sim.device().c_str(), 115200, error)) << error;
  auto parser = std::make_unique<NmeaParser>();
  std::array<uint8_t, 512> buf{};
  Counting c;
  const int64_t end = rt::monotonic_ns() + 300 * rt::kNsPerMs;
  while (rt::monotonic_ns() < end) {
    const IoResult r = port.read(buf, 20 * rt::kNsPerMs);
    if (r.status == IoStatus::kOk) parser->feed(std::span<const uint8_t>(buf.data(), r.bytes));
  }
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_GT(parser->counters().sentences, 20U);
  sim.stop();
}

TEST(DriverNoAllocTest, TcpLinkReadAndColaParsing) {
  test::Watchdog w;
  sims::SickLms1xxSim sim({});
  sim.start();
  TcpSensorLink link;
  TcpSensorConfig cfg;
  cfg.port = sim.port();
  const std::string start = "\x02sEN LMDscandata 1\x03";
  cfg.greeting.assign(start.begin(), start.end());
  link.open(cfg);
  std::thread runner([&link] { link.run(); });  // in rackd: the component's I/O worker
  auto parser = std::make_unique<cola::Parser>();
  std::vector<uint8_t> buf(8192);
  ASSERT_TRUE(test::eventually([&] { return link.connected(); }));
  Counting c;
  const int64_t end = rt::monotonic_ns() + 300 * rt::kNsPerMs;
  while (rt::monotonic_ns() < end) {
    const IoResult r = link.read(buf, 20 * rt::kNsPerMs);
    if (r.status == IoStatus::kOk) parser->feed(std::span<const uint8_t>(buf.data(), r.bytes), nullptr, nullptr);
  }
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_GT(parser->counters().scans, 5U);
  link.request_stop();
  runner.join();
  link.close();
  sim.stop();
}

TEST(DriverNoAllocTest, ScipParsing) {
  auto parser = std::make_unique<scip::Parser>();
  std::string data;
  for (uint32_t i = 0; i < 682; ++i) {
    char e[3];
    scip::encode3(1000 + i, e);
    data.append(e, 3);
  }
  std::string scan = "MD0044072501000\n99b\n0000";
  scan += scip::checksum("0000", 4);
  scan += "\n";
  for (std::size_t at = 0; at < data.size(); at += 64) {
    const std::string chunk = data.substr(at, 64);
    scan += chunk + scip::checksum(chunk.data(), chunk.size()) + "\n";
  }
  scan += "\n";
  Counting c;
  std::size_t n = 0;
  for (int i = 0; i < 50; ++i) {
    n += parser->feed(std::span(reinterpret_cast<const uint8_t*>(scan.data()), scan.size()), nullptr, nullptr);
  }
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_EQ(n, 50U);
  EXPECT_EQ(parser->scan().count, 682U);
}

}  // namespace
}  // namespace rack::devices
