// The driver components in an in-process executor against the shipped simulators:
// GpsNmea on a pty, ChassisCan on the CiA 402 simulator's CAN-frame socket, Joystick
// on a FIFO carrying struct js_event. Each test covers the normal path, malformed
// traffic, and a device that disappears or falls silent and comes back.
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <linux/joystick.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "../unit/test_support.h"
#include "joystick/obstacle.h"
#include "rack/components/class_ids.h"
#include "rack/devices/canopen.h"
#include "gps_nmea/gps_nmea_types.h"
#include "joystick/joystick_types.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/robot.h"
#include "rack/sims/cia402_sim.h"
#include "rack/sims/hokuyo_scip_sim.h"
#include "rack/sims/nmea_gps_sim.h"
#include "rack/sims/sick_lms1xx_sim.h"

namespace rack {
namespace {

using interfaces::ChassisData;
using interfaces::GpsData;
using interfaces::JoystickData;
using interfaces::LadarData;
using test::HostUnderTest;
using test::Watchdog;
using tims::Address;
namespace msg = tims::msg;

std::string temp_path(const std::string& what) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return "/tmp/rack-" + what + "-" + std::to_string(::getpid()) + "-" + info->name();
}

template <typename T>
bool wait_sample(HostUnderTest& host, Address a, T& out, const std::function<bool(const T&)>& pred,
                 std::chrono::milliseconds limit = std::chrono::milliseconds(10000)) {
  return test::eventually(
      [&] {
        wire::SampleHeader h;
        return host.get_data(a, h, out) && pred(out);
      },
      limit);
}

// ---------------------------------------------------------------------------

class GpsNmeaTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sims::NmeaGpsSim::Config c;
    c.link = temp_path("gps");
    c.period_ns = 20 * rt::kNsPerMs;
    c.course_deg = 90.0;  // due east
    c.speed_mps = 2.0;
    config_ = c;
    sim_ = std::make_unique<sims::NmeaGpsSim>(c);
    sim_->start();
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: gps
    class: GpsNmea
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 10, ring: 64}
    params:
      device: )" + c.link + R"(
      baud: 115200
      device_timeout_ms: 300
      origin_latitude_deg: )" + std::to_string(c.latitude_deg) +
                                            R"(
      origin_longitude_deg: )" + std::to_string(c.longitude_deg) +
                                            "\n");
    gps_ = host_->address_of("gps");
  }
  void TearDown() override {
    if (HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
    sim_.reset();
  }
  sims::NmeaGpsSim::Config config_;
  std::unique_ptr<sims::NmeaGpsSim> sim_;
  std::unique_ptr<HostUnderTest> host_;
  Address gps_;
};

TEST_F(GpsNmeaTest, PublishesTheFixInWgs84UtmAndTheLocalFrame) {
  Watchdog w;
  GpsData d;
  ASSERT_TRUE(wait_sample<GpsData>(*host_, gps_, d, [](const GpsData& g) { return g.sentences >= 20; }));
  EXPECT_EQ(d.fix_quality, interfaces::kGpsFixGps);
  EXPECT_EQ(d.fix_mode, 3);
  EXPECT_EQ(d.satellites, config_.satellites);
  EXPECT_NEAR(d.latitude_deg, config_.latitude_deg, 1e-4);
  EXPECT_NEAR(d.speed, 2.0, 0.01);
  EXPECT_NEAR(d.course_deg, 90.0, 0.1);
  EXPECT_EQ(d.utm_zone, 32U);  // 9.7 E
  EXPECT_EQ(d.utm_north, 1);
  EXPECT_NEAR(d.utm_easting, 550000.0, 5000.0);
  EXPECT_GT(d.utm_northing, 5.8e6);
  EXPECT_EQ(d.checksum_errors, 0U);
  // Driving east at 2 m/s from the origin: x grows, y stays near 0 (NMEA rounds to ~0.2 m).
  GpsData later;
  ASSERT_TRUE(wait_sample<GpsData>(*host_, gps_, later, [&](const GpsData& g) { return g.x > d.x + 0.5; }));
  EXPECT_GT(later.x, 0.0);
  EXPECT_LT(std::fabs(later.y), 1.0);
  EXPECT_NEAR(static_cast<double>(later.utc_ns), static_cast<double>(rt::host_time_ns()), 5e9);
}

TEST_F(GpsNmeaTest, GarbageIsCountedWhileTheFixGoesOn) {
  Watchdog w;
  GpsData d;
  ASSERT_TRUE(wait_sample<GpsData>(*host_, gps_, d, [](const GpsData& g) { return g.sentences > 0; }));
  sim_->set_fault(sims::NmeaGpsSim::Fault::kGarbage);
  ASSERT_TRUE(wait_sample<GpsData>(*host_, gps_, d, [](const GpsData& g) {
    return g.garbage_bytes > 50 && g.malformed > 3 && g.checksum_errors == 0;
  }));
  EXPECT_EQ(host_->status(gps_), msg::kEnabled) << "half epochs still carry GGA: the fix goes on";
}

TEST_F(GpsNmeaTest, WrongChecksumsAndSilenceAreErrorsAndItRecovers) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(gps_, msg::kEnabled));
  sim_->set_fault(sims::NmeaGpsSim::Fault::kBadChecksum);
  ASSERT_TRUE(host_->wait_status(gps_, msg::kError)) << "no valid sentence for device_timeout_ms";
  sim_->set_fault(sims::NmeaGpsSim::Fault::kNone);
  ASSERT_TRUE(host_->wait_status(gps_, msg::kEnabled)) << "on() retries and the receiver talks again";
  GpsData d;
  ASSERT_TRUE(wait_sample<GpsData>(*host_, gps_, d, [](const GpsData& g) { return g.checksum_errors >= 8; }))
      << "the rejected sentences were counted";
  sim_->set_fault(sims::NmeaGpsSim::Fault::kSilent);
  ASSERT_TRUE(host_->wait_status(gps_, msg::kError));
  sim_->set_fault(sims::NmeaGpsSim::Fault::kNone);
  EXPECT_TRUE(host_->wait_status(gps_, msg::kEnabled));
}

TEST_F(GpsNmeaTest, AnUnpluggedReceiverIsAnErrorAndComesBackUnderANewDevice) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(gps_, msg::kEnabled));
  sim_->unplug();
  ASSERT_TRUE(host_->wait_status(gps_, msg::kError));
  sim_->plug();  // a new pty; the symlink moves, as udev would move /dev/gps0
  ASSERT_TRUE(host_->wait_status(gps_, msg::kEnabled));
  wire::SampleHeader h1, h2;
  GpsData d;
  ASSERT_TRUE(test::eventually([&] { return host_->get_data(gps_, h1, d); }));  // the ring restarts at ON
  EXPECT_TRUE(test::eventually([&] { return host_->get_data(gps_, h2, d) && h2.sequence > h1.sequence; }));
}

// ---------------------------------------------------------------------------

class ChassisCanTest : public ::testing::Test {
 protected:
  void SetUp() override {
    socket_ = temp_path("can") + ".sock";
    sim_ = std::make_unique<sims::Cia402DriveSim>(sims::Cia402DriveSim::Config{});
    sim_->listen_unix(socket_);
    sim_->start();
  }
  void start_host(const std::string& extra = "") {
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: chassis
    class: ChassisCan
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 10, ring: 64}
    params:
      can: unix:)" + socket_ + R"(
      counts_per_meter: 10000
      track_width: 0.5
      acc_max: 5.0
      dec_max: 5.0
      heartbeat_ms: 20
      heartbeat_timeout_ms: 400
      sdo_timeout_ms: 200
      max_missed_syncs: 50
      watchdog_ms: 300
)" + extra,
                                            std::function<void(ComponentRegistry&)>{}, /*capture_gdos=*/true);
    chassis_ = host_->address_of("chassis");
  }
  void TearDown() override {
    if (HasFailure() && host_) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
    sim_.reset();
  }
  // Timeouts are generous (tolerant of a loaded 2-CPU machine); the behaviour, not the
  // timing, is what these tests check. The test's own tool mailbox is the pilot.
  [[nodiscard]] uint32_t me() const { return Address::make(0, tims::classes::kTool, 1, 0).raw(); }
  HostUnderTest::Reply move(double vx, double omega) {
    const interfaces::ChassisMove m{vx, 0.0, omega};
    return host_->call_with(chassis_, interfaces::kChassisMove, m);
  }
  HostUnderTest::Reply set_pilot(uint32_t pilot) {
    const interfaces::ChassisSetActivePilot p{pilot};
    return host_->call_with(chassis_, interfaces::kChassisSetActivePilot, p);
  }

  std::string socket_;
  std::unique_ptr<sims::Cia402DriveSim> sim_;
  std::unique_ptr<HostUnderTest> host_;
  Address chassis_;
};

TEST_F(ChassisCanTest, DrivesBothWheelsAndPublishesOdometry) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  // on() sent NMT start last; the simulator takes it within its 1 ms tick.
  EXPECT_TRUE(test::eventually([&] { return sim_->state(1).nmt == 0x05 && sim_->state(2).nmt == 0x05; }))
      << "NMT operational";
  EXPECT_EQ(sim_->state(1).mode, 3) << "profile velocity mode, configured over SDO";
  EXPECT_EQ(sim_->state(2).heartbeat_ms, 20);
  ASSERT_EQ(set_pilot(me()).type, msg::kOk);
  // Keep MOVE coming faster than the watchdog.
  ChassisData d;
  const int64_t end = rt::monotonic_ns() + 3 * rt::kNsPerSec;
  bool reached = false;
  while (!reached && rt::monotonic_ns() < end) {
    (void)move(0.5, 0.0);  // tolerant: a loaded machine may delay the first cycles
    wire::SampleHeader h;
    reached = host_->get_data(chassis_, h, d) && std::fabs(d.vx - 0.5) < 0.01;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(reached) << "vx " << d.vx;
  EXPECT_EQ(sim_->state(1).target_velocity, 5000);
  EXPECT_EQ(sim_->state(2).target_velocity, 5000);
  EXPECT_NEAR(d.omega, 0.0, 1e-6);
  // Straight ahead: a cycle whose TPDOs all came within half a period has no rotation.
  // (On a loaded machine a late TPDO moves one wheel's increment to the next cycle.)
  ASSERT_TRUE(test::eventually([&] {
    (void)move(0.5, 0.0);
    wire::SampleHeader h;
    // delta_x: 0.5 m/s for one 10 ms cycle (SYNCs are as regular as the data task).
    return host_->get_data(chassis_, h, d) && std::fabs(d.vx - 0.5) < 0.01 && std::fabs(d.delta_phi) < 1e-9 &&
           std::fabs(d.delta_x - 0.005) < 0.0015;
  })) << "vx "
      << d.vx << " delta_phi " << d.delta_phi << " delta_x " << d.delta_x;
  EXPECT_EQ(d.active_pilot, me());
  // Turning on the spot: the left wheel backwards, the right forwards.
  ASSERT_EQ(move(0.0, 1.0).type, msg::kOk);
  EXPECT_TRUE(test::eventually([&] {
    (void)move(0.0, 1.0);
    return sim_->state(1).target_velocity == -2500 && sim_->state(2).target_velocity == 2500;
  }));
  ASSERT_TRUE(test::eventually([&] {
    (void)move(0.0, 1.0);  // keeps the watchdog fed
    wire::SampleHeader h;
    return host_->get_data(chassis_, h, d) && std::fabs(d.omega - 1.0) < 0.01;
  }));
  EXPECT_GT(d.delta_phi, 0.0);
  // GET_PARAMS.
  const auto r = host_->call(chassis_, interfaces::kChassisGetParams);
  ASSERT_EQ(r.type, interfaces::kChassisParamsReply);
  interfaces::ChassisParams p;
  ASSERT_EQ(r.body.size(), sizeof p);
  std::memcpy(&p, r.body.data(), sizeof p);
  EXPECT_DOUBLE_EQ(p.vx_max, 1.0);
  EXPECT_EQ(p.watchdog_ns, 300 * rt::kNsPerMs);
}

TEST_F(ChassisCanTest, OnlyTheActivePilotMovesAndVelocitiesAreClamped) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  auto r = move(0.3, 0.0);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("no active pilot"), std::string::npos) << r.error_text();
  ASSERT_EQ(set_pilot(Address::make(0, class_ids::kPilot, 7, 0).raw()).type, msg::kOk);
  r = move(0.3, 0.0);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("not the active pilot"), std::string::npos) << r.error_text();
  ASSERT_EQ(set_pilot(me()).type, msg::kOk);
  EXPECT_EQ(move(5.0, 0.0).type, msg::kOk);
  EXPECT_TRUE(test::eventually([&] { return sim_->state(1).target_velocity == 10000; })) << "clamped to vx_max 1 m/s";
  // Malformed bodies are answered ERROR and counted.
  const uint8_t junk[3] = {1, 2, 3};
  EXPECT_EQ(host_->call(chassis_, interfaces::kChassisMove, junk, sizeof junk).type, msg::kError);
  const interfaces::ChassisMove nan{std::nan(""), 0.0, 0.0};
  EXPECT_EQ(host_->call_with(chassis_, interfaces::kChassisMove, nan).type, msg::kError);
  EXPECT_GE(host_->stats(chassis_).malformed, 2U);
  // Changing the pilot stops the robot.
  ASSERT_EQ(set_pilot(0).type, msg::kOk);
  EXPECT_TRUE(test::eventually([&] { return sim_->state(1).target_velocity == 0; }));
}

TEST_F(ChassisCanTest, TheWatchdogStopsTheRobotWhenMovesStop) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  ASSERT_EQ(set_pilot(me()).type, msg::kOk);
  ASSERT_EQ(move(0.2, 0.0).type, msg::kOk);
  ASSERT_TRUE(test::eventually([&] { return sim_->state(1).target_velocity == 2000; }));
  // No more MOVEs: within watchdog_ms (300) plus a cycle the targets are zero.
  ChassisData d;
  ASSERT_TRUE(
      wait_sample<ChassisData>(*host_, chassis_, d, [](const ChassisData& c) { return c.watchdog_stops == 1; }));
  EXPECT_EQ(sim_->state(1).target_velocity, 0);
  EXPECT_EQ(sim_->state(2).target_velocity, 0);
  EXPECT_EQ(host_->status(chassis_), msg::kEnabled) << "a watchdog stop is not an error";
}

TEST_F(ChassisCanTest, ASilentDriveIsAnErrorStopsTheOtherAndRecovery) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  ASSERT_EQ(set_pilot(me()).type, msg::kOk);
  // Tolerant of a loaded machine: MOVE again until the wheels turn.
  ASSERT_TRUE(test::eventually([&] {
    (void)move(0.2, 0.0);
    return sim_->state(1).velocity > 1000;
  }));
  sim_->set_silent(2, true);  // the right drive loses power
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kError, std::chrono::milliseconds(3000)));
  EXPECT_EQ(sim_->state(1).target_velocity, 0) << "the left drive was stopped";
  EXPECT_EQ(sim_->state(1).velocity, 0.0);
  EXPECT_NE(move(0.2, 0.0).type, msg::kOk) << "no MOVE while in ERROR";
  sim_->set_silent(2, false);
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled)) << "on() retried and reconfigured both drives";
  EXPECT_EQ(sim_->state(2).statusword & 0x6F, 0x27);
}

// A drive that drops out of NMT OPERATIONAL (local control, an internal reset) stops
// the robot like a silent one; while it ignores the master's NMT start, every retry
// ends in ERROR again (it never reports OPERATIONAL); once it obeys, the chassis runs.
TEST_F(ChassisCanTest, ADriveOutOfNmtOperationalIsAnErrorUntilItTakesTheStart) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  ASSERT_EQ(set_pilot(me()).type, msg::kOk);
  ASSERT_TRUE(test::eventually([&] {
    (void)move(0.2, 0.0);
    return sim_->state(1).velocity > 1000;
  }));
  sim_->hold_nmt(2, devices::canopen::kStatePreOperational);
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kError, std::chrono::milliseconds(3000)));
  EXPECT_EQ(sim_->state(1).target_velocity, 0) << "the left drive was stopped";
  EXPECT_TRUE(test::eventually([&] {
    return host_->gdos_log().find("a drive left the NMT state OPERATIONAL") != std::string::npos;
  })) << host_->gdos_log();
  // Held: the retries' NMT start is ignored, and each ON ends in ERROR again.
  EXPECT_TRUE(test::eventually(
      [&] { return host_->gdos_log().find("did not report the NMT state OPERATIONAL") != std::string::npos; },
      std::chrono::milliseconds(5000)))
      << host_->gdos_log();
  EXPECT_NE(move(0.2, 0.0).type, msg::kOk) << "no MOVE while in ERROR";
  sim_->release_nmt(2);
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled, std::chrono::milliseconds(5000))) << host_->gdos_log();
  EXPECT_TRUE(test::eventually([&] { return sim_->state(2).nmt == devices::canopen::kStateOperational; }));
}

TEST_F(ChassisCanTest, GarbageOnTheBusIsIgnoredAndALostConnectionRecovers) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  sim_->inject_garbage(20);
  wire::SampleHeader h1, h2;
  ChassisData d;
  ASSERT_TRUE(test::eventually([&] { return host_->get_data(chassis_, h1, d); }));  // the ring restarts at ON
  ASSERT_TRUE(test::eventually([&] { return host_->get_data(chassis_, h2, d) && h2.sequence > h1.sequence + 20; }));
  EXPECT_EQ(host_->status(chassis_), msg::kEnabled);
  sim_->drop_client();  // the cable is pulled and plugged back in
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kError));
  EXPECT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
}

// The same driver on a real SocketCAN interface, the drive simulator on another
// CAN_RAW socket of the same vcan0. Needs AF_CAN and vcan0.
TEST(ChassisCanVcanTest, DrivesTheSimulatorOnVcan0) {
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0)
    GTEST_SKIP() << "this kernel has no AF_CAN (" << std::strerror(errno)
                 << "); ChassisCanTest runs the same driver over AF_UNIX";
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, "vcan0", IFNAMSIZ - 1);
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) != 0) {
    ::close(fd);
    GTEST_SKIP() << "no vcan0 (ip link add vcan0 type vcan && ip link set vcan0 up)";
  }
  addr.can_ifindex = ifr.ifr_ifindex;
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  Watchdog w;
  sims::Cia402DriveSim sim({});
  sim.attach(fd);
  sim.start();
  HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: chassis
    class: ChassisCan
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 10}
    params:
      can: vcan0
      heartbeat_ms: 20
      heartbeat_timeout_ms: 400
      sdo_timeout_ms: 200
)");
  const Address chassis = host.address_of("chassis");
  EXPECT_TRUE(host.wait_status(chassis, msg::kEnabled)) << host.log();
  EXPECT_TRUE(test::eventually([&] { return sim.state(1).nmt == 0x05; }));
  sim.stop();
}

TEST_F(ChassisCanTest, BusOffIsAnErrorAndTheChassisRecoversAfterTheRestart) {
  Watchdog w;
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
  // The controller goes bus-off: no frames either way until it restarts 1 s later.
  sim_->inject_bus_off(1000 * rt::kNsPerMs);
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kError)) << "no TPDOs: ERROR after max_missed_syncs";
  EXPECT_TRUE(host_->wait_status(chassis_, msg::kEnabled)) << "after the restart on() succeeds again";
}

TEST_F(ChassisCanTest, NoSimulatorMeansErrorUntilItAppears) {
  Watchdog w;
  sim_.reset();
  start_host();
  ASSERT_TRUE(host_->wait_status(chassis_, msg::kError));
  sim_ = std::make_unique<sims::Cia402DriveSim>(sims::Cia402DriveSim::Config{});
  sim_->listen_unix(socket_);
  sim_->start();
  EXPECT_TRUE(host_->wait_status(chassis_, msg::kEnabled));
}

// ---------------------------------------------------------------------------

class JoystickTest : public ChassisCanTest {
 protected:
  void SetUp() override {
    ChassisCanTest::SetUp();
    fifo_ = temp_path("js");
    ::unlink(fifo_.c_str());
    ASSERT_EQ(::mkfifo(fifo_.c_str(), 0600), 0);
    open_writer();
  }
  void TearDown() override {
    ChassisCanTest::TearDown();
    if (writer_ >= 0) ::close(writer_);
    ::unlink(fifo_.c_str());
  }
  void open_writer() {
    // O_RDWR: a FIFO opened for writing this way never blocks and never sees EPIPE.
    writer_ = ::open(fifo_.c_str(), O_RDWR | O_NONBLOCK);
    ASSERT_GE(writer_, 0);
  }
  void event(uint8_t type, uint8_t number, int16_t value) {
    js_event e{};
    e.time = 0;
    e.type = type;
    e.number = number;
    e.value = value;
    ASSERT_EQ(::write(writer_, &e, sizeof e), static_cast<ssize_t>(sizeof e));
  }
  void start_joystick(bool deadman, const std::string& extra_params = "", const std::string& extra_components = "") {
    start_host(extra_components + R"(  - name: joystick
    class: Joystick
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 20, ring: 64}
    params:
      device: )" +
               fifo_ + R"(
      chassis: chassis
      deadman_button: )" +
               (deadman ? "0" : "-1") + "\n" + extra_params);
    joystick_ = host_->address_of("joystick");
  }
  std::string fifo_;
  int writer_ = -1;
  Address joystick_;
};

TEST_F(JoystickTest, TheStickDrivesTheChassisAsActivePilot) {
  Watchdog w;
  start_joystick(/*deadman=*/true);
  ASSERT_TRUE(host_->wait_status(joystick_, msg::kEnabled));
  ASSERT_EQ(host_->status(chassis_), msg::kEnabled) << "cascading ON";
  event(JS_EVENT_AXIS | JS_EVENT_INIT, 0, 0);
  event(JS_EVENT_AXIS | JS_EVENT_INIT, 1, 0);
  event(JS_EVENT_AXIS, 1, -32767);  // full forward
  JoystickData j;
  ASSERT_TRUE(wait_sample<JoystickData>(*host_, joystick_, j, [](const JoystickData& s) { return s.events >= 3; }));
  EXPECT_FLOAT_EQ(j.axis[1], -1.0F);
  EXPECT_EQ(j.vx, 0.0) << "dead-man button not held";
  event(JS_EVENT_BUTTON, 0, 1);
  ASSERT_TRUE(wait_sample<JoystickData>(*host_, joystick_, j, [](const JoystickData& s) { return s.vx > 0.0; }));
  EXPECT_DOUBLE_EQ(j.vx, 0.5) << "vx_max 1 m/s * speed_scale 0.5";
  EXPECT_EQ(j.buttons, 1U);
  ChassisData c;
  ASSERT_TRUE(wait_sample<ChassisData>(*host_, chassis_, c, [](const ChassisData& s) { return s.vx > 0.45; }));
  EXPECT_EQ(c.active_pilot, joystick_.raw());
  // Turn left: axis 0 negative is left on Linux; omega positive (counter-clockwise).
  event(JS_EVENT_AXIS, 0, -16384);
  ASSERT_TRUE(wait_sample<ChassisData>(*host_, chassis_, c, [](const ChassisData& s) { return s.omega > 0.5; }));
  // Releasing the dead-man button stops the robot.
  event(JS_EVENT_BUTTON, 0, 0);
  EXPECT_TRUE(
      wait_sample<ChassisData>(*host_, chassis_, c, [](const ChassisData& s) { return std::fabs(s.vx) < 1e-3; }));
}

TEST_F(JoystickTest, ForwardSpeedIsLimitedByTheFreeSpaceAheadInALadarScan) {
  Watchdog w;
  sims::HokuyoScipSim::Config c;
  c.link = temp_path("urg");
  c.room_front = 2.0;  // a wall 2 m ahead of the scanner
  c.scan_rpm = 1200;
  sims::HokuyoScipSim urg(c);
  urg.start();
  start_joystick(false, "      obstacles: ladar\n      slow_distance: 3.2\n", R"(  - name: ladar
    class: LadarHokuyo
    instance: 0
    retry_ms: 100
    data_task: {period_ms: 10, ring: 8}
    params:
      device: )" + c.link + "\n      device_timeout_ms: 300\n");
  ASSERT_TRUE(host_->wait_status(joystick_, msg::kEnabled));
  event(JS_EVENT_AXIS, 1, -32767);  // full forward: 0.5 m/s without obstacles
  // Free ahead: 2.0 m - boundary_front 0.3 - safety_margin 0.1 = 1.6 m; over 3.2 m: half.
  JoystickData j;
  ASSERT_TRUE(wait_sample<JoystickData>(*host_, joystick_, j, [](const JoystickData& s) { return s.vx > 0.0; }));
  EXPECT_NEAR(j.free_ahead, 1.6, 0.01);
  EXPECT_NEAR(j.vx, 0.25, 0.01);
  event(JS_EVENT_AXIS, 1, 32767);  // backwards is not limited by what is ahead
  ASSERT_TRUE(wait_sample<JoystickData>(*host_, joystick_, j, [](const JoystickData& s) { return s.vx < -0.45; }));
  // The scanner goes away: its listeners get ERROR, the joystick stops the robot.
  event(JS_EVENT_AXIS, 1, -32767);
  urg.unplug();
  ASSERT_TRUE(host_->wait_status(joystick_, msg::kError));
  ChassisData cd;
  EXPECT_TRUE(wait_sample<ChassisData>(*host_, chassis_, cd, [](const ChassisData& s) {
    return std::fabs(s.vx) < 1e-3 && s.active_pilot == 0;
  }));
  urg.stop();
}

TEST_F(JoystickTest, BadEventsAreCountedAndAnUnpluggedStickStopsTheRobot) {
  Watchdog w;
  start_joystick(/*deadman=*/false);
  ASSERT_TRUE(host_->wait_status(joystick_, msg::kEnabled));
  event(0x40, 0, 1);              // unknown type
  event(JS_EVENT_AXIS, 200, 5);   // axis out of range
  event(JS_EVENT_BUTTON, 40, 1);  // button out of range
  event(JS_EVENT_AXIS, 1, -32767);
  JoystickData j;
  ASSERT_TRUE(wait_sample<JoystickData>(*host_, joystick_, j, [](const JoystickData& s) { return s.events >= 1; }));
  EXPECT_EQ(j.bad_events, 3U);
  ChassisData c;
  ASSERT_TRUE(wait_sample<ChassisData>(*host_, chassis_, c, [](const ChassisData& s) { return s.vx > 0.45; }));
  ::close(writer_);  // the stick is unplugged
  writer_ = -1;
  ASSERT_TRUE(host_->wait_status(joystick_, msg::kError));
  ASSERT_TRUE(wait_sample<ChassisData>(*host_, chassis_, c, [](const ChassisData& s) {
    return std::fabs(s.vx) < 1e-3 && s.active_pilot == 0;
  })) << "the joystick stopped the robot and released the chassis";
  open_writer();
  EXPECT_TRUE(host_->wait_status(joystick_, msg::kEnabled));
}

// ---------------------------------------------------------------------------

TEST(ObstacleTest, FreeAheadInTheCorridorFromScan2dAndLadar) {
  auto s = std::make_unique<interfaces::Scan2dData>();
  s->point_count = 4;
  s->x[0] = 2.0F, s->y[0] = 0.1F;   // ahead, in the corridor
  s->x[1] = 1.0F, s->y[1] = 0.9F;   // nearer but beside the corridor
  s->x[2] = -0.5F, s->y[2] = 0.0F;  // behind
  s->x[3] = 0.5F, s->y[3] = 0.0F;
  s->type[3] = interfaces::kScanPointMaxRange;  // no echo
  EXPECT_NEAR(components::obstacle::free_ahead(*s, 0.4, 0.5), 1.6, 1e-6);
  s->x[0] = 0.2F;  // inside the outline: no free space at all
  EXPECT_EQ(components::obstacle::free_ahead(*s, 0.4, 0.5), 0.0);
  auto l = std::make_unique<LadarData>();
  l->beam_count = 3;
  l->start_angle = static_cast<float>(-M_PI / 2);
  l->angle_step = static_cast<float>(M_PI / 2);
  l->max_range = 10.0F;
  l->range[0] = 1.0F;  // right, beside the corridor
  l->range[1] = 3.0F;  // straight ahead
  l->range[2] = 0.0F;  // no echo
  EXPECT_NEAR(components::obstacle::free_ahead(*l, 0.5, 0.4), 2.5, 1e-5);
  l->beam_count = 0;
  EXPECT_TRUE(std::isinf(components::obstacle::free_ahead(*l, 0.5, 0.4)));
}

class LadarHokuyoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sims::HokuyoScipSim::Config c;
    c.link = temp_path("urg");
    c.scan_rpm = 1200;  // 20 Hz keeps the test short
    config_ = c;
    sim_ = std::make_unique<sims::HokuyoScipSim>(c);
    sim_->start();
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: ladar
    class: LadarHokuyo
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 10, ring: 16}
    params:
      device: )" + c.link + R"(
      device_timeout_ms: 300
)");
    ladar_ = host_->address_of("ladar");
  }
  void TearDown() override {
    if (HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
    sim_.reset();
  }
  bool next_scan(LadarData& d, uint64_t after_sequence, wire::SampleHeader& h) {
    return test::eventually([&] { return host_->get_data(ladar_, h, d) && h.sequence > after_sequence; });
  }
  sims::HokuyoScipSim::Config config_;
  std::unique_ptr<sims::HokuyoScipSim> sim_;
  std::unique_ptr<HostUnderTest> host_;
  Address ladar_;
};

TEST_F(LadarHokuyoTest, ReadsTheParametersAndPublishesContinuousScans) {
  Watchdog w;
  auto d = std::make_unique<LadarData>();
  wire::SampleHeader h;
  ASSERT_TRUE(next_scan(*d, 0, h));
  EXPECT_TRUE(sim_->streaming()) << "MD started";
  EXPECT_EQ(d->beam_count, 725U - 44U + 1U);
  const double step = 2.0 * M_PI / 1024.0;
  EXPECT_NEAR(d->start_angle, (44.0 - 384.0) * step, 1e-6);
  EXPECT_NEAR(d->angle_step, step, 1e-7);
  EXPECT_FLOAT_EQ(d->max_range, 5.6F);
  EXPECT_NEAR(d->range[384 - 44], 2.0, 1e-3) << "the wall ahead";
  EXPECT_NEAR(d->range[640 - 44], 1.5, 1e-3) << "the wall to the left (counter-clockwise)";
  EXPECT_NEAR(d->range[128 - 44], 1.5, 1e-3) << "the wall to the right";
  for (uint32_t i = 0; i < d->beam_count; ++i) {
    EXPECT_EQ(d->range[i], static_cast<float>(sim_->range_mm(44 + i)) * 1e-3F) << "beam " << i;
    if (HasFailure()) break;
  }
  EXPECT_GT(d->duration_ns, 0);
  EXPECT_LT(h.time_ns, rt::host_time_ns());
  wire::SampleHeader h2;
  ASSERT_TRUE(next_scan(*d, h.sequence + 3, h2)) << "continuous output";
}

TEST_F(LadarHokuyoTest, CorruptScansAreDroppedThenErrorAndRecovery) {
  Watchdog w;
  auto d = std::make_unique<LadarData>();
  wire::SampleHeader h;
  ASSERT_TRUE(next_scan(*d, 0, h));
  for (const auto fault : {sims::HokuyoScipSim::Fault::kBadChecksum, sims::HokuyoScipSim::Fault::kGarbage,
                           sims::HokuyoScipSim::Fault::kSilent}) {
    sim_->set_fault(fault);
    ASSERT_TRUE(host_->wait_status(ladar_, msg::kError)) << "no valid scan for device_timeout_ms";
    sim_->set_fault(sims::HokuyoScipSim::Fault::kNone);
    ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled)) << "on() restarted the output";
    ASSERT_TRUE(test::eventually([&] { return host_->get_data(ladar_, h, *d); }));
    EXPECT_NEAR(d->range[384 - 44], 2.0, 1e-3);
  }
}

TEST_F(LadarHokuyoTest, AnUnpluggedScannerIsAnErrorAndComesBack) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled));
  sim_->unplug();
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kError));
  sim_->plug();
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled));
  auto d = std::make_unique<LadarData>();
  wire::SampleHeader h;
  EXPECT_TRUE(next_scan(*d, 0, h));
}

// ---------------------------------------------------------------------------

class LadarSickTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sim_ = std::make_unique<sims::SickLms1xxSim>(sims::SickLms1xxSim::Config{});
    sim_->start();
    port_ = sim_->port();
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: ladar
    class: LadarSick
    instance: 1
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 5, ring: 16}
    params:
      host: 127.0.0.1
      port: )" + std::to_string(port_) + R"(
      device_timeout_ms: 300
)");
    ladar_ = host_->address_of("ladar");
  }
  void TearDown() override {
    if (HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
    sim_.reset();
  }
  uint16_t port_ = 0;
  std::unique_ptr<sims::SickLms1xxSim> sim_;
  std::unique_ptr<HostUnderTest> host_;
  Address ladar_;
};

TEST_F(LadarSickTest, StartsContinuousOutputAndPublishesScans) {
  Watchdog w;
  auto d = std::make_unique<LadarData>();
  wire::SampleHeader h;
  ASSERT_TRUE(test::eventually([&] { return host_->get_data(ladar_, h, *d); }));
  EXPECT_TRUE(sim_->streaming()) << "the link's greeting started the output";
  EXPECT_EQ(d->beam_count, 541U);
  EXPECT_NEAR(d->start_angle, -135.0 * M_PI / 180.0, 1e-6) << "SICK -45 deg is the robot's -135 deg";
  EXPECT_NEAR(d->angle_step, 0.5 * M_PI / 180.0, 1e-7);
  EXPECT_NEAR(d->range[270], 2.0, 1e-3) << "straight ahead";
  EXPECT_NEAR(d->range[450], 1.5, 1e-3) << "left";
  for (uint32_t i = 0; i < d->beam_count; ++i) {
    EXPECT_NEAR(d->range[i], sim_->range_m(i), 1e-6) << "beam " << i;
    if (HasFailure()) break;
  }
  EXPECT_GT(d->intensity[0], 0.0F) << "RSSI1";
  wire::SampleHeader h2;
  EXPECT_TRUE(test::eventually([&] { return host_->get_data(ladar_, h2, *d) && h2.sequence > h.sequence + 5; }));
}

TEST_F(LadarSickTest, GarbageIsToleratedTruncationAndSilenceAreErrorsAndItRecovers) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled));
  auto d = std::make_unique<LadarData>();
  wire::SampleHeader h1, h2;
  ASSERT_TRUE(test::eventually([&] { return host_->get_data(ladar_, h1, *d); }));
  sim_->set_fault(sims::SickLms1xxSim::Fault::kGarbage);
  ASSERT_TRUE(test::eventually([&] { return host_->get_data(ladar_, h2, *d) && h2.sequence > h1.sequence + 10; }))
      << "garbage between telegrams costs nothing";
  EXPECT_EQ(host_->status(ladar_), msg::kEnabled);
  for (const auto fault : {sims::SickLms1xxSim::Fault::kTruncated, sims::SickLms1xxSim::Fault::kSilent}) {
    sim_->set_fault(fault);
    ASSERT_TRUE(host_->wait_status(ladar_, msg::kError));
    sim_->set_fault(sims::SickLms1xxSim::Fault::kNone);
    ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled));
  }
}

TEST_F(LadarSickTest, ALostConnectionAndASwitchedOffScannerRecover) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled));
  sim_->drop_client();
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kError));
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kEnabled)) << "the link reconnected and restarted the output";
  sim_.reset();  // switched off
  ASSERT_TRUE(host_->wait_status(ladar_, msg::kError));
  sims::SickLms1xxSim::Config c;
  c.port = port_;
  sim_ = std::make_unique<sims::SickLms1xxSim>(c);
  sim_->start();
  EXPECT_TRUE(host_->wait_status(ladar_, msg::kEnabled));
}

// ---------------------------------------------------------------------------

class ServoDriveCanTest : public ::testing::Test {
 protected:
  void SetUp() override {
    socket_ = temp_path("servo") + ".sock";
    sim_ = std::make_unique<sims::Cia402DriveSim>(sims::Cia402DriveSim::Config{{3}, 1'000'000});
    sim_->listen_unix(socket_);
    sim_->start();
    start_host();
  }
  void start_host() {
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: servo
    class: ServoDriveCan
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 10, ring: 32}
    params:
      can: unix:)" + socket_ + R"(
      node: 3
      counts_per_unit: 10000
      max_velocity: 2.0
      acceleration: 10.0
      position_min: -1.0
      position_max: 1.0
      heartbeat_ms: 20
      heartbeat_timeout_ms: 400
      sdo_timeout_ms: 200
)");
    servo_ = host_->address_of("servo");
    // A mailbox of our own that receives the POSITION_REACHED notifications.
    mailbox_ = std::make_unique<tims::Mailbox>(Address::make(0, tims::classes::kTool, 2, 1), 8, 256);
    host_->executor().router().add(*mailbox_);
    endpoint_ = std::make_unique<tims::Endpoint>(host_->executor().router(), *mailbox_, 10);
  }
  void TearDown() override {
    if (HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_->executor().stop();
    host_->executor().router().remove(mailbox_->address());
    host_.reset();
    sim_.reset();
  }
  int8_t call(int8_t type, const void* body, std::size_t size) {
    std::array<std::byte, 256> buf{};
    const tims::ConstBuffer part{body, size};
    const auto r = endpoint_->call(servo_, type, std::span<const tims::ConstBuffer>(&part, size == 0 ? 0 : 1), buf,
                                   test::kCallTimeoutNs);
    return r.status == tims::CallStatus::kOk ? r.reply.type : int8_t{99};
  }
  int8_t move_pos(double position, double velocity) {
    const interfaces::ServoDriveMovePos m{position, velocity};
    return call(interfaces::kServoDriveMovePos, &m, sizeof m);
  }
  // The next POSITION_REACHED notification's position, or NaN after 10 s.
  double reached() {
    std::array<std::byte, 256> buf{};
    const int64_t end = rt::monotonic_ns() + 10 * rt::kNsPerSec;
    while (rt::monotonic_ns() < end) {
      const auto r = mailbox_->receive(buf, 100 * rt::kNsPerMs);
      if (r.status != tims::RecvStatus::kOk || r.header.type != interfaces::kServoDrivePositionReached) continue;
      double at;
      std::memcpy(&at, buf.data() + sizeof(tims::MessageHeader), sizeof at);
      return at;
    }
    return std::nan("");
  }
  std::string socket_;
  std::unique_ptr<sims::Cia402DriveSim> sim_;
  std::unique_ptr<HostUnderTest> host_;
  std::unique_ptr<tims::Mailbox> mailbox_;
  std::unique_ptr<tims::Endpoint> endpoint_;
  Address servo_;
};

TEST_F(ServoDriveCanTest, HomeMoveToPositionAndPositionReached) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(servo_, msg::kEnabled));
  EXPECT_EQ(sim_->state(3).mode, 1) << "profile position mode, configured over SDO";
  EXPECT_EQ(move_pos(0.5, 0.0), msg::kError) << "MOVE_POS before HOME";
  ASSERT_EQ(call(interfaces::kServoDriveHome, nullptr, 0), msg::kOk);
  ASSERT_EQ(move_pos(0.5, 1.0), msg::kOk);
  const double at = reached();
  EXPECT_NEAR(at, 0.5, 1e-3) << "drive: position " << sim_->state(3).position << " statusword " << std::hex
                             << sim_->state(3).statusword << " target " << std::dec << sim_->state(3).target_position
                             << " active " << sim_->state(3).active_target << " rpdos " << sim_->state(3).rpdos
                             << " syncs " << sim_->state(3).syncs << " status " << int(host_->status(servo_))
                             << " errors " << host_->stats(servo_).errors;
  interfaces::ServoDriveData d;
  ASSERT_TRUE(wait_sample<interfaces::ServoDriveData>(*host_, servo_, d, [](const interfaces::ServoDriveData& s) {
    return s.target_reached == 1;
  }));
  EXPECT_NEAR(d.position, 0.5, 1e-3);
  EXPECT_EQ(d.homed, 1);
  EXPECT_EQ(d.reached, 1U);
  EXPECT_NEAR(sim_->state(3).position, 5000.0, 1.0) << "0.5 unit = 5000 counts from home";
  // Back, then beyond the limit (refused), then a second move.
  ASSERT_EQ(move_pos(-0.25, 2.0), msg::kOk);
  EXPECT_NEAR(reached(), -0.25, 1e-3);
  EXPECT_EQ(move_pos(1.5, 1.0), msg::kError) << "outside [position_min, position_max]";
  const uint8_t junk[3] = {};
  EXPECT_EQ(call(interfaces::kServoDriveMovePos, junk, sizeof junk), msg::kError);
}

TEST_F(ServoDriveCanTest, MoveAtVelocityStopsAtTheLimitAndASilentDriveIsAnError) {
  Watchdog w;
  ASSERT_TRUE(host_->wait_status(servo_, msg::kEnabled));
  ASSERT_EQ(call(interfaces::kServoDriveHome, nullptr, 0), msg::kOk);
  const interfaces::ServoDriveMoveVel v{2.0};
  ASSERT_EQ(call(interfaces::kServoDriveMoveVel, &v, sizeof v), msg::kOk);
  interfaces::ServoDriveData d;
  ASSERT_TRUE(wait_sample<interfaces::ServoDriveData>(*host_, servo_, d, [](const interfaces::ServoDriveData& s) {
    return s.velocity > 1.5;
  }));
  ASSERT_TRUE(wait_sample<interfaces::ServoDriveData>(*host_, servo_, d, [](const interfaces::ServoDriveData& s) {
    return s.target_reached == 1;
  }));
  EXPECT_NEAR(d.position, 1.0, 1e-3) << "stopped at position_max";
  sim_->set_silent(3, true);
  ASSERT_TRUE(host_->wait_status(servo_, msg::kError));
  sim_->set_silent(3, false);
  EXPECT_TRUE(host_->wait_status(servo_, msg::kEnabled));
}

// A missing bus: on() fails through CanPort's CanError forms (no allocation in the
// command task on the retries) and the ERROR's reason is the port's own words.
TEST_F(ServoDriveCanTest, NoBusThenBus) {
  Watchdog w;
  host_->executor().stop();
  host_->executor().router().remove(mailbox_->address());
  host_.reset();
  sim_.reset();
  ::unlink(socket_.c_str());
  start_host();
  ASSERT_TRUE(host_->wait_status(servo_, msg::kError));
  wire::StatsReply s;
  ASSERT_TRUE(test::eventually([&] {
    s = host_->stats(servo_);
    return std::string(s.error_reason).find(": connect: No such file or directory") != std::string::npos;
  })) << s.error_reason;
  EXPECT_EQ(std::string(s.error_reason).rfind(socket_, 0), 0U) << "names the socket: " << s.error_reason;
  sim_ = std::make_unique<sims::Cia402DriveSim>(sims::Cia402DriveSim::Config{{3}, 1'000'000});
  sim_->listen_unix(socket_);
  sim_->start();
  EXPECT_TRUE(host_->wait_status(servo_, msg::kEnabled));
}

// ---------------------------------------------------------------------------

#if RACK_HAVE_CAMERA
// An image sequence of PPM files written here (OpenCV's image-sequence backend reads
// them), 64 x 48, frame i filled with the colour (i, 2i, 3i) and one marked pixel.
class CameraTest : public ::testing::Test {
 protected:
  static constexpr int kW = 64, kH = 48, kFrames = 20;
  void SetUp() override {
    dir_ = temp_path("cam");
    std::filesystem::create_directories(dir_);
    for (int i = 0; i < kFrames; ++i) {
      char name[64];
      std::snprintf(name, sizeof name, "/img_%03d.ppm", i);
      FILE* f = std::fopen((dir_ + name).c_str(), "wb");
      ASSERT_NE(f, nullptr);
      std::fprintf(f, "P6\n%d %d\n255\n", kW, kH);
      for (int p = 0; p < kW * kH; ++p) {
        const uint8_t px[3] = {static_cast<uint8_t>(i), static_cast<uint8_t>(2 * i),
                               static_cast<uint8_t>(p == 5 * kW + 7 ? 255 : 3 * i)};
        std::fwrite(px, 1, 3, f);
      }
      std::fclose(f);
    }
    calibration_ = dir_ + "/calib.yaml";
    FILE* c = std::fopen(calibration_.c_str(), "w");
    std::fputs(
        "%YAML:1.0\n---\nimage_width: 128\nimage_height: 96\n"
        "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
        "   data: [ 200., 0., 64., 0., 210., 48., 0., 0., 1. ]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
        "   data: [ 0.1, -0.2, 0.001, 0.002, 0.05 ]\n",
        c);
    std::fclose(c);
  }
  void TearDown() override {
    if (HasFailure() && host_) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    if (host_) {
      host_->executor().stop();
      if (mailbox_) host_->executor().router().remove(mailbox_->address());
    }
    host_.reset();
    std::filesystem::remove_all(dir_);
  }
  void start(const std::string& params) {
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: camera
    class: Camera
    instance: 0
    autostart: true
    retry_ms: 100
    data_task: {period_ms: 10, ring: 4}
    params:
)" + params);
    camera_ = host_->address_of("camera");
    // CameraData is 0.9 MB: GET_DATA needs a mailbox with slots that large.
    mailbox_ = std::make_unique<tims::Mailbox>(Address::make(0, tims::classes::kTool, 3, 1), 2, 1100 * 1024);
    host_->executor().router().add(*mailbox_);
    endpoint_ = std::make_unique<tims::Endpoint>(host_->executor().router(), *mailbox_, 10);
    buffer_.resize(1100 * 1024);
  }
  bool get(interfaces::CameraData& d, wire::SampleHeader& h) {
    const auto r = endpoint_->call(camera_, msg::kGetData, std::span<std::byte>(buffer_), test::kCallTimeoutNs);
    if (r.status != tims::CallStatus::kOk || r.reply.type != msg::kData || r.body.size() != sizeof h + sizeof d) {
      return false;
    }
    std::memcpy(&h, r.body.data(), sizeof h);
    std::memcpy(&d, r.body.data() + sizeof h, sizeof d);
    return true;
  }
  std::string dir_, calibration_;
  std::unique_ptr<HostUnderTest> host_;
  std::unique_ptr<tims::Mailbox> mailbox_;
  std::unique_ptr<tims::Endpoint> endpoint_;
  std::vector<std::byte> buffer_;
  Address camera_;
};

TEST_F(CameraTest, AnImageSequenceWithCalibrationIsPublishedThenItsEndIsAnError) {
  Watchdog w;
  start("      source: " + dir_ + "/img_%03d.ppm\n      fps: 50\n      calibration: " + calibration_ + "\n");
  auto d = std::make_unique<interfaces::CameraData>();
  wire::SampleHeader h;
  ASSERT_TRUE(test::eventually([&] { return get(*d, h) && d->frame >= 3; }));
  EXPECT_EQ(d->width, 64U);
  EXPECT_EQ(d->height, 48U);
  EXPECT_EQ(d->format, interfaces::kCameraRgb8);
  EXPECT_EQ(d->bytes, 64U * 48U * 3U);
  const int i = static_cast<int>(d->frame) - 1;  // frame n shows img_(n-1)
  EXPECT_EQ(d->data[0], i);
  EXPECT_EQ(d->data[1], 2 * i);
  EXPECT_EQ(d->data[2], 3 * i);
  EXPECT_EQ(d->data[(5 * 64 + 7) * 3 + 2], 255) << "rows top to bottom, RGB order";
  EXPECT_EQ(d->calibrated, 1);
  EXPECT_DOUBLE_EQ(d->fx, 100.0) << "calibrated at 128x96: the matrix scales to 64x48";
  EXPECT_DOUBLE_EQ(d->fy, 105.0);
  EXPECT_DOUBLE_EQ(d->cx, 32.0);
  EXPECT_DOUBLE_EQ(d->distortion[4], 0.05);
  EXPECT_LE(h.time_ns, rt::host_time_ns());
  // 20 frames at 50 fps: then the sequence ends and the camera is in ERROR.
  EXPECT_TRUE(host_->wait_status(camera_, msg::kError));
}

TEST_F(CameraTest, JpegAndLooping) {
  Watchdog w;
  start("      source: " + dir_ + "/img_%03d.ppm\n      fps: 200\n      format: jpeg\n      loop: true\n");
  auto d = std::make_unique<interfaces::CameraData>();
  wire::SampleHeader h;
  ASSERT_TRUE(test::eventually([&] { return get(*d, h) && d->frame > kFrames + 5; })) << "looped past the end";
  EXPECT_EQ(d->format, interfaces::kCameraJpeg);
  ASSERT_GT(d->bytes, 4U);
  EXPECT_EQ(d->data[0], 0xFF);
  EXPECT_EQ(d->data[1], 0xD8) << "a JPEG starts with SOI";
  EXPECT_EQ(host_->status(camera_), msg::kEnabled);
}

TEST_F(CameraTest, MonoIsOneBytePerPixel) {
  Watchdog w;
  start("      source: " + dir_ + "/img_%03d.ppm\n      fps: 50\n      format: mono\n");
  auto d = std::make_unique<interfaces::CameraData>();
  wire::SampleHeader h;
  ASSERT_TRUE(test::eventually([&] { return get(*d, h) && d->frame >= 5; }));
  EXPECT_EQ(d->format, interfaces::kCameraMono8);
  EXPECT_EQ(d->bytes, 64U * 48U);
  const int i = static_cast<int>(d->frame) - 1;
  EXPECT_NEAR(d->data[0], 0.299 * i + 0.587 * 2 * i + 0.114 * 3 * i, 1.0) << "ITU-R BT.601 luma";
}

TEST_F(CameraTest, AMissingSourceIsAnErrorAndABadCalibrationFailsInit) {
  Watchdog w;
  start("      source: " + dir_ + "/nothing_%03d.ppm\n      timeout_ms: 300\n");
  EXPECT_TRUE(host_->wait_status(camera_, msg::kError));
  host_.reset();
  FILE* c = std::fopen(calibration_.c_str(), "w");
  std::fputs("%YAML:1.0\n---\nimage_width: 10\n", c);
  std::fclose(c);
  start("      source: " + dir_ + "/img_%03d.ppm\n      calibration: " + calibration_ + "\n");
  const auto r = host_->call(camera_, msg::kOn);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("calibration"), std::string::npos) << r.error_text();
}
#endif

}  // namespace
}  // namespace rack
