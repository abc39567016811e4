// SerialPort over a pseudo-terminal, CanPort over a socketpair (the same read/write
// path as SocketCAN) and over real AF_CAN where the kernel has it, TcpSensorLink
// against a local server that goes away and comes back.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pty.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include "../unit/hostile_files.h"
#include "../unit/test_support.h"
#include "rack/devices/can_port.h"
#include "rack/devices/canopen.h"
#include "rack/devices/serial_port.h"
#include "rack/devices/tcp_sensor_link.h"
#include "rack/rt/clock.h"

namespace rack::devices {
namespace {

using test::Watchdog;
constexpr int64_t kMs = rt::kNsPerMs;

class PtyPair {
 public:
  PtyPair() {
    char name[256];
    if (::openpty(&master_, &slave_, name, nullptr, nullptr) != 0) throw std::runtime_error("openpty");
    path_ = name;
  }
  ~PtyPair() {
    close_master();
    if (slave_ >= 0) ::close(slave_);
  }
  void close_master() {
    if (master_ >= 0) ::close(master_);
    master_ = -1;
  }
  [[nodiscard]] int master() const { return master_; }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  int master_ = -1, slave_ = -1;
  std::string path_;
};

TEST(SerialPortTest, ReadsBytesFromThePtyWithATimestamp) {
  Watchdog w;
  PtyPair pty;
  SerialPort port;
  std::string error;
  ASSERT_TRUE(port.open(pty.path().c_str(), 115200, error)) << error;
  EXPECT_FALSE(port.low_latency()) << "a pty has no ASYNC_LOW_LATENCY; the port must say so";
  const int64_t before = rt::host_time_ns();
  ASSERT_EQ(::write(pty.master(), "hello\n", 6), 6);
  std::array<uint8_t, 64> buf{};
  std::string got;
  while (got.size() < 6) {
    const IoResult r = port.read(buf, 1000 * kMs);
    ASSERT_EQ(r.status, IoStatus::kOk) << describe(r.status);
    EXPECT_GE(r.stamp_ns, before);
    EXPECT_LE(r.stamp_ns, rt::host_time_ns());
    got.append(reinterpret_cast<const char*>(buf.data()), r.bytes);
  }
  EXPECT_EQ(got, "hello\n") << "raw mode: no translation of bytes";
}

TEST(SerialPortTest, WritesReachTheDevice) {
  Watchdog w;
  PtyPair pty;
  termios t{};
  ::tcgetattr(pty.master(), &t);
  ::cfmakeraw(&t);
  ::tcsetattr(pty.master(), TCSANOW, &t);
  SerialPort port;
  std::string error;
  ASSERT_TRUE(port.open(pty.path().c_str(), 19200, error)) << error;
  const uint8_t cmd[] = {'M', 'D', '0', '\n'};
  const IoResult r = port.write_all(cmd, 1000 * kMs);
  ASSERT_EQ(r.status, IoStatus::kOk);
  char buf[8] = {};
  ASSERT_EQ(::read(pty.master(), buf, sizeof buf), 4);
  EXPECT_EQ(std::string(buf, 4), "MD0\n");
}

TEST(SerialPortTest, TimesOutWhenTheDeviceIsSilent) {
  Watchdog w;
  PtyPair pty;
  SerialPort port;
  std::string error;
  ASSERT_TRUE(port.open(pty.path().c_str(), 9600, error)) << error;
  std::array<uint8_t, 8> buf{};
  EXPECT_EQ(port.read(buf, 20 * kMs).status, IoStatus::kTimeout);
  EXPECT_EQ(port.read(buf, 0).status, IoStatus::kTimeout);
}

TEST(SerialPortTest, ReportsClosedWhenTheDeviceGoesAway) {
  Watchdog w;
  auto pty = std::make_unique<PtyPair>();
  SerialPort port;
  std::string error;
  ASSERT_TRUE(port.open(pty->path().c_str(), 115200, error)) << error;
  pty->close_master();
  std::array<uint8_t, 8> buf{};
  EXPECT_EQ(port.read(buf, 500 * kMs).status, IoStatus::kClosed);
}

TEST(SerialPortTest, OpenErrorsNameThePathAndTheReason) {
  SerialPort port;
  std::string error;
  EXPECT_FALSE(port.open("/dev/does-not-exist-rack", 115200, error));
  EXPECT_NE(error.find("/dev/does-not-exist-rack"), std::string::npos) << error;
  EXPECT_NE(error.find("No such file"), std::string::npos) << error;
  PtyPair pty;
  EXPECT_FALSE(port.open(pty.path().c_str(), 12345, error));
  EXPECT_NE(error.find("unsupported baud rate 12345"), std::string::npos) << error;
  EXPECT_FALSE(port.open("/dev/null", 9600, error)) << "not a tty";
  EXPECT_NE(error.find("not a tty"), std::string::npos) << error;
  EXPECT_FALSE(port.is_open());
}

// Issue 17: a device path must name a device. A regular file, FIFO or directory put
// where the serial port should be is refused with what it is, without waiting on it.
TEST(SerialPortTest, ARegularFileOrFifoWhereThePortShouldBeIsRefused) {
  test::HostileDir d("serial");
  const std::string file = d.write("ttyUSB0", "$GPGGA,not a port\r\n");
  const std::string fifo = d.fifo("ttyS0");
  test::HangGuard guard("SerialPort::open on a FIFO");
  SerialPort port;
  std::string error;
  EXPECT_FALSE(port.open(file.c_str(), 9600, error));
  EXPECT_EQ(error, file + ": the serial port is a regular file, not a character device (a tty)");
  EXPECT_FALSE(port.open(fifo.c_str(), 9600, error));
  EXPECT_EQ(error, fifo + ": the serial port is a FIFO, not a character device (a tty)");
  EXPECT_FALSE(port.open(d.dir().c_str(), 9600, error));
  EXPECT_NE(error.find("the serial port is a directory"), std::string::npos) << error;
  EXPECT_FALSE(port.is_open());
  CanPort can;
  EXPECT_FALSE(can.open(("unix:" + file).c_str(), error));
  EXPECT_EQ(error, file + ": the CAN bus socket is a regular file, not a socket");
}

// ---------------------------------------------------------------------------

class CanPortTest : public ::testing::Test {
 protected:
  void SetUp() override {
    int sv[2];
    ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    port_.adopt(sv[0]);
    peer_ = sv[1];
  }
  void TearDown() override {
    if (peer_ >= 0) ::close(peer_);
  }
  void peer_send(canid_t id, std::initializer_list<uint8_t> data) {
    can_frame f{};
    f.can_id = id;
    f.len = static_cast<uint8_t>(data.size());
    std::copy(data.begin(), data.end(), f.data);
    ASSERT_EQ(::send(peer_, &f, sizeof f, 0), static_cast<ssize_t>(sizeof f));
  }
  CanPort port_;
  int peer_ = -1;
};

TEST_F(CanPortTest, FramesRoundTripWithKernelReceiveTimestamps) {
  Watchdog w;
  const int64_t before = rt::host_time_ns();
  peer_send(0x181, {1, 2, 3, 4, 5, 6, 7, 8});
  can_frame f{};
  const IoResult r = port_.receive(f, 1000 * kMs);
  ASSERT_EQ(r.status, IoStatus::kOk);
  EXPECT_EQ(f.can_id, 0x181U);
  EXPECT_EQ(f.len, 8);
  EXPECT_EQ(f.data[7], 8);
  EXPECT_GE(r.stamp_ns, before);
  EXPECT_LE(r.stamp_ns, rt::host_time_ns());
  const uint8_t d[] = {0x01, 0x05};
  ASSERT_EQ(port_.send(make_frame(0x000, d)).status, IoStatus::kOk);
  can_frame back{};
  ASSERT_EQ(::recv(peer_, &back, sizeof back, 0), static_cast<ssize_t>(sizeof back));
  EXPECT_EQ(back.can_id, 0x000U);
  EXPECT_EQ(back.len, 2);
  EXPECT_EQ(back.data[1], 0x05);
  EXPECT_EQ(port_.counters().received, 1U);
  EXPECT_EQ(port_.counters().sent, 1U);
}

TEST_F(CanPortTest, TimesOutWhenTheBusIsSilent) {
  Watchdog w;
  can_frame f{};
  EXPECT_EQ(port_.receive(f, 20 * kMs).status, IoStatus::kTimeout);
}

TEST_F(CanPortTest, FiltersDropOtherIdsAndCountThem) {
  Watchdog w;
  const can_filter filters[] = {{0x180, 0x780}, {0x700, 0x780}};  // TPDO1 and heartbeats of any node
  std::string error;
  ASSERT_TRUE(port_.set_filters(filters, error)) << error;
  peer_send(0x601, {0x40});
  peer_send(0x285, {1});
  peer_send(0x705, {5});
  can_frame f{};
  ASSERT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kOk);
  EXPECT_EQ(f.can_id, 0x705U);
  EXPECT_EQ(port_.counters().filtered, 2U);
  // Inverted filter: everything except heartbeats.
  const can_filter inv[] = {{0x700 | CAN_INV_FILTER, 0x780}};
  ASSERT_TRUE(port_.set_filters(inv, error));
  peer_send(0x701, {5});
  peer_send(0x181, {5});
  ASSERT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kOk);
  EXPECT_EQ(f.can_id, 0x181U);
}

TEST_F(CanPortTest, MalformedPacketsAreCountedAndSkipped) {
  Watchdog w;
  const uint8_t junk[5] = {1, 2, 3, 4, 5};
  ASSERT_EQ(::send(peer_, junk, sizeof junk, 0), 5);
  can_frame bad{};
  bad.can_id = 0x100;
  bad.len = 12;  // dlc beyond 8
  ASSERT_EQ(::send(peer_, &bad, sizeof bad, 0), static_cast<ssize_t>(sizeof bad));
  uint8_t big[72] = {};  // a CAN FD sized packet
  ASSERT_EQ(::send(peer_, big, sizeof big, 0), static_cast<ssize_t>(sizeof big));
  peer_send(0x200, {9});
  can_frame f{};
  ASSERT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kOk);
  EXPECT_EQ(f.can_id, 0x200U);
  EXPECT_EQ(port_.counters().malformed, 3U);
}

TEST_F(CanPortTest, BusOffStopsSendingUntilTheControllerRestarts) {
  Watchdog w;
  peer_send(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0});
  can_frame f{};
  ASSERT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kOk);
  EXPECT_NE(f.can_id & CAN_ERR_FLAG, 0U) << "error frames are handed to the caller to log";
  EXPECT_TRUE(port_.error_passive());
  EXPECT_FALSE(port_.bus_off());
  peer_send(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kOk);
  EXPECT_TRUE(port_.bus_off());
  EXPECT_EQ(port_.counters().bus_off, 1U);
  const IoResult s = port_.send(canopen::sync());
  EXPECT_EQ(s.status, IoStatus::kError);
  EXPECT_EQ(s.error, ENETDOWN);
  peer_send(CAN_ERR_FLAG | CAN_ERR_RESTARTED, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kOk);
  EXPECT_FALSE(port_.bus_off());
  EXPECT_EQ(port_.send(canopen::sync()).status, IoStatus::kOk);
  EXPECT_EQ(port_.counters().error_frames, 3U);
  EXPECT_EQ(port_.counters().send_failed, 1U);
}

TEST_F(CanPortTest, PeerCloseIsReportedAsClosed) {
  Watchdog w;
  ::close(peer_);
  peer_ = -1;
  can_frame f{};
  EXPECT_EQ(port_.receive(f, 1000 * kMs).status, IoStatus::kClosed);
  EXPECT_EQ(port_.send(canopen::sync()).status, IoStatus::kClosed);
}

TEST(CanPortOpenTest, UnixSpecConnectsAndMissingPeerIsANamedError) {
  CanPort port;
  std::string error;
  EXPECT_FALSE(port.open("unix:/tmp/rack-no-such-bus.sock", error));
  EXPECT_NE(error.find("/tmp/rack-no-such-bus.sock"), std::string::npos) << error;
}

// Real SocketCAN: needs a kernel with CAN_RAW and a vcan0 interface
// (modprobe vcan; ip link add vcan0 type vcan; ip link set vcan0 up).
TEST(CanPortSocketCanTest, RoundTripOnVcan0) {
  const int probe = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (probe < 0)
    GTEST_SKIP() << "this kernel has no AF_CAN (" << std::strerror(errno)
                 << "); the same path is covered over AF_UNIX by CanPortTest";
  ::close(probe);
  Watchdog w;
  CanPort a, b;
  std::string error;
  if (!a.open("vcan0", error)) GTEST_SKIP() << "no vcan0: " << error;
  ASSERT_TRUE(b.open("vcan0", error)) << error;
  const uint8_t d[] = {0xAA};
  ASSERT_EQ(a.send(make_frame(0x123, d)).status, IoStatus::kOk);
  can_frame f{};
  const IoResult r = b.receive(f, 1000 * kMs);
  ASSERT_EQ(r.status, IoStatus::kOk);
  EXPECT_EQ(f.can_id, 0x123U);
  EXPECT_GT(r.stamp_ns, 0);
}

// can-utils as the peer: cansend's frame reaches CanPort, CanPort's frame reaches
// candump. Needs AF_CAN, vcan0 and can-utils (scripts/setup.sh installs can-utils).
TEST(CanPortSocketCanTest, CansendAndCandumpArePeersOnVcan0) {
  const int probe = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (probe < 0)
    GTEST_SKIP() << "this kernel has no AF_CAN (" << std::strerror(errno)
                 << "); the same path is covered over AF_UNIX by CanPortTest";
  ::close(probe);
  if (std::system("command -v cansend >/dev/null && command -v candump >/dev/null") != 0) {
    GTEST_SKIP() << "can-utils (cansend, candump) not installed";
  }
  Watchdog w;
  CanPort port;
  std::string error;
  if (!port.open("vcan0", error)) GTEST_SKIP() << "no vcan0: " << error;
  ASSERT_EQ(std::system("cansend vcan0 123#DEADBEEF"), 0);
  can_frame f{};
  ASSERT_EQ(port.receive(f, 2 * rt::kNsPerSec).status, IoStatus::kOk);
  EXPECT_EQ(f.can_id, 0x123U);
  EXPECT_EQ(f.len, 4);
  EXPECT_EQ(f.data[0], 0xDE);
  FILE* dump = ::popen("timeout 5 candump -n 1 vcan0", "r");
  ASSERT_NE(dump, nullptr);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // candump binds first
  const uint8_t d[] = {0x01, 0x02};
  ASSERT_EQ(port.send(make_frame(0x321, d)).status, IoStatus::kOk);
  char line[256] = {};
  const bool got = std::fgets(line, sizeof line, dump) != nullptr;
  ::pclose(dump);
  ASSERT_TRUE(got) << "candump printed nothing";
  EXPECT_NE(std::string(line).find("321"), std::string::npos) << line;
}

// ---------------------------------------------------------------------------

class TestServer {
 public:
  explicit TestServer(uint16_t port = 0) {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const int on = 1;
    ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 4) != 0) {
      throw std::runtime_error("bind");
    }
    socklen_t len = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  }
  ~TestServer() {
    if (client_ >= 0) ::close(client_);
    ::close(fd_);
  }
  int accept_one() {
    client_ = ::accept(fd_, nullptr, nullptr);
    return client_;
  }
  [[nodiscard]] uint16_t port() const { return port_; }

 private:
  int fd_ = -1;
  int client_ = -1;
  uint16_t port_ = 0;
};

std::string read_exact(TcpSensorLink& link, std::size_t n) {
  std::string out;
  std::array<uint8_t, 256> buf{};
  const int64_t end = rt::monotonic_ns() + 5 * rt::kNsPerSec;
  while (out.size() < n && rt::monotonic_ns() < end) {
    const IoResult r = link.read(std::span(buf.data(), std::min(buf.size(), n - out.size())), 100 * kMs);
    if (r.status == IoStatus::kOk) out.append(reinterpret_cast<const char*>(buf.data()), r.bytes);
  }
  return out;
}

// The link makes no thread (in rackd its run() is the component's I/O worker, in an
// executor-owned thread): here the test gives it one.
class LinkThread {
 public:
  LinkThread(TcpSensorLink& link, const TcpSensorConfig& config) : link_(link) {
    link_.open(config);
    thread_ = std::thread([this] { link_.run(); });
  }
  ~LinkThread() {
    link_.request_stop();
    thread_.join();
    link_.close();
  }
  LinkThread(const LinkThread&) = delete;
  LinkThread& operator=(const LinkThread&) = delete;

 private:
  TcpSensorLink& link_;
  std::thread thread_;
};

TEST(TcpSensorLinkTest, SendsTheGreetingAndReconnectsAfterTheSensorGoesAway) {
  Watchdog w;
  auto server = std::make_unique<TestServer>();
  const uint16_t port = server->port();
  TcpSensorLink link;
  TcpSensorConfig c;
  c.port = port;
  c.greeting = {'h', 'i'};
  c.min_backoff_ns = 20 * kMs;
  c.max_backoff_ns = 200 * kMs;
  const LinkThread running(link, c);
  int client = server->accept_one();
  ASSERT_GE(client, 0);
  char g[2];
  ASSERT_EQ(::recv(client, g, 2, MSG_WAITALL), 2);
  EXPECT_EQ(std::string(g, 2), "hi");
  ASSERT_EQ(::send(client, "scan1", 5, 0), 5);
  EXPECT_EQ(read_exact(link, 5), "scan1");
  EXPECT_TRUE(link.connected());
  // The sensor goes away: the reader learns it once (kClosed), then times out.
  server.reset();
  std::array<uint8_t, 16> buf{};
  IoStatus s = IoStatus::kTimeout;
  for (int i = 0; i < 50 && s != IoStatus::kClosed; ++i) s = link.read(buf, 100 * kMs).status;
  EXPECT_EQ(s, IoStatus::kClosed);
  EXPECT_EQ(link.read(buf, 10 * kMs).status, IoStatus::kTimeout);
  EXPECT_TRUE(test::eventually([&] { return link.failed_connects() >= 2; }))
      << "it keeps trying while the sensor is away";
  // It comes back on the same port: the link connects again and greets it again.
  server = std::make_unique<TestServer>(port);
  client = server->accept_one();
  ASSERT_GE(client, 0);
  ASSERT_EQ(::recv(client, g, 2, MSG_WAITALL), 2);
  ASSERT_EQ(::send(client, "scan2", 5, 0), 5);
  EXPECT_EQ(read_exact(link, 5), "scan2");
  EXPECT_EQ(link.connects(), 2U);
  EXPECT_EQ(link.disconnects(), 1U);
}

TEST(TcpSensorLinkTest, RequestedReconnectDropsTheConnection) {
  Watchdog w;
  TestServer server;
  TcpSensorLink link;
  TcpSensorConfig c;
  c.port = server.port();
  c.min_backoff_ns = 10 * kMs;
  const LinkThread running(link, c);
  ASSERT_GE(server.accept_one(), 0);
  ASSERT_TRUE(test::eventually([&] { return link.connected(); }));
  link.request_reconnect();
  ASSERT_GE(server.accept_one(), 0) << "a second connection after request_reconnect()";
  EXPECT_TRUE(test::eventually([&] { return link.connects() == 2; }));
}

TEST(TcpSensorLinkTest, OverflowDropsAndCountsBytesInsteadOfBlocking) {
  Watchdog w;
  TestServer server;
  TcpSensorLink link;
  TcpSensorConfig c;
  c.port = server.port();
  c.ring_bytes = 4096;
  const LinkThread running(link, c);
  const int client = server.accept_one();
  ASSERT_GE(client, 0);
  std::string big(20000, 'x');
  ASSERT_EQ(::send(client, big.data(), big.size(), 0), static_cast<ssize_t>(big.size()));
  EXPECT_TRUE(test::eventually([&] { return link.dropped_bytes() > 0; }));
  std::array<uint8_t, 8192> buf{};
  const IoResult r = link.read(buf, 100 * kMs);
  ASSERT_EQ(r.status, IoStatus::kOk);
  EXPECT_LE(r.bytes, 4096U);
}

}  // namespace
}  // namespace rack::devices
