// ChassisReplay and LadarReplay in a real executor: a CARMEN log played as Chassis
// increments and Ladar scans on one clock, at a chosen speed; a malformed log puts the
// replay components in ERROR with the file and line while the rest runs.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <vector>

#include "rack/interfaces/robot.h"
#include "test_support.h"

namespace rack::test {
namespace {

using interfaces::ChassisData;
using interfaces::LadarData;

class ReplayComponentTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("rack_replay_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // A robot driving a quarter circle: ODOM at 20 Hz, ROBOTLASER1 at 10 Hz, 2 s.
  std::string write_log() {
    std::ostringstream out;
    // A first ODOM 1 s before the rest starts the replay clock and leaves the test
    // 250 ms (at speed 4) to subscribe before the data it checks plays.
    out << "# CARMEN Logfile (test)\nPARAM robot_width 0.5 nohost 0\nODOM 0 0 0 0 0 0 99.0 host 99.0\n";
    for (int i = 0; i <= 40; ++i) {
      const double t = 100.0 + i * 0.05;
      const double a = i * 0.05 * 0.5;  // 0.5 rad/s on a 1 m radius
      const double x = std::sin(a), y = 1.0 - std::cos(a);
      out << "ODOM " << x << " " << y << " " << a << " 0.5 0.5 0 " << t << " host " << t << "\n";
      if (i % 2 == 0) {
        out << "ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 7";
        for (int b = 0; b < 7; ++b) out << " " << (1.0 + b + i * 0.01);
        out << " 0 " << x + 0.2 * std::cos(a) << " " << y + 0.2 * std::sin(a) << " " << a << " " << x << " " << y << " "
            << a << " 0.5 0.5 0 0 0 " << t << " host " << t << "\n";
      }
    }
    return write("robot.log", out.str());
  }
  std::string write(const std::string& name, const std::string& text) {
    const auto p = dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  static std::string host(const std::string& log, double speed) {
    std::ostringstream y;
    y << "lcm: false\ncomponents:\n"
         "  - name: chassis\n    class: ChassisReplay\n    data_task: {priority: 40, period_ms: 5, ring: 200}\n"
         "    params: {log: \""
      << log << "\", speed: " << speed
      << "}\n"
         "  - name: ladar\n    class: LadarReplay\n    data_task: {priority: 40, period_ms: 5, ring: 100}\n"
         "    params: {log: \""
      << log << "\", speed: " << speed << "}\n"
      << "  - name: gen\n    class: Generator\n    autostart: true\n    data_task: {period_ms: 10}\n";
    return y.str();
  }
  std::filesystem::path dir_;
};

TEST_F(ReplayComponentTest, PlaysOdometryAsChassisIncrementsAndScansAsLadarInStep) {
  Watchdog watchdog;
  const std::string log = write_log();
  HostUnderTest h(host(log, 4.0));  // 2 s of log in 0.5 s
  const auto chassis = h.address_of("chassis");
  const auto ladar = h.address_of("ladar");
  // Listen to both from a mailbox of this test (scans are 8.7 KB: bigger slots than
  // the tool's data mailbox has).
  tims::Mailbox inbox(tims::Address::make(0, tims::classes::kTool, 1, 3), 128, 16 * 1024);
  h.executor().router().add(inbox);
  struct Unregister {
    HostUnderTest& h;
    tims::Mailbox& m;
    ~Unregister() {
      h.executor().stop();
      h.executor().router().remove(m.address());
    }
  } unregister{h, inbox};
  wire::ContDataRequest req;
  req.period_ns = 0;
  req.mailbox = inbox.address().raw();
  ASSERT_EQ(h.call(chassis, tims::msg::kOn).type, tims::msg::kOk) << h.log();
  ASSERT_EQ(h.call(ladar, tims::msg::kOn).type, tims::msg::kOk) << h.log();
  ASSERT_EQ(h.call_with(chassis, tims::msg::kGetContData, req).type, tims::msg::kContData);
  ASSERT_EQ(h.call_with(ladar, tims::msg::kGetContData, req).type, tims::msg::kContData);

  double x = 0, y = 0, phi = 0;
  int odom = 0, scans = 0;
  std::vector<int64_t> odom_ns;
  int64_t first_scan_ns = 0;
  auto buf = std::make_unique<std::byte[]>(64 * 1024);
  const int64_t end = rt::monotonic_ns() + 5 * rt::kNsPerSec;
  // Until the log has played out (the first ODOM may have been missed): everything
  // seen, then 200 ms of silence.
  int64_t last_rx = rt::monotonic_ns();
  while (rt::monotonic_ns() < end) {
    const auto p = inbox.peek(50 * rt::kNsPerMs);
    if (p.status != tims::RecvStatus::kOk) {
      if (odom >= 41 && scans >= 21 && rt::monotonic_ns() - last_rx > 200 * rt::kNsPerMs) break;
      continue;
    }
    last_rx = rt::monotonic_ns();
    const tims::MessageHeader hd = *p.header;
    wire::SampleHeader sh{};
    if (hd.src == chassis.raw()) {
      ChassisData d;
      if (read_sample(hd, p.body, sh, d)) {
        // Integrate the increments (each in the previous pose's frame).
        x += d.delta_x * std::cos(phi) - d.delta_y * std::sin(phi);
        y += d.delta_x * std::sin(phi) + d.delta_y * std::cos(phi);
        phi += d.delta_phi;
        odom_ns.push_back(sh.time_ns);
        ++odom;
      }
    } else if (hd.src == ladar.raw()) {
      auto d = std::make_unique<LadarData>();
      if (read_sample(hd, p.body, sh, *d)) {
        EXPECT_EQ(d->beam_count, 7U);
        EXPECT_FLOAT_EQ(d->start_angle, -1.5F);
        EXPECT_FLOAT_EQ(d->angle_step, 0.5F);
        EXPECT_NEAR(d->range[6], 7.0 + scans * 2 * 0.01, 1e-4);
        if (scans == 0) first_scan_ns = sh.time_ns;
        ++scans;
      }
    }
    inbox.peek_end();
  }
  ASSERT_GE(odom, 41);
  ASSERT_LE(odom, 42);
  EXPECT_EQ(scans, 21);
  // The last ODOM: a = 1 rad on the unit circle.
  EXPECT_NEAR(x, std::sin(1.0), 1e-4);
  EXPECT_NEAR(y, 1.0 - std::cos(1.0), 1e-4);
  EXPECT_NEAR(phi, 1.0, 1e-4);
  // One clock: the first scan and the first ODOM share a log time, so a host time; 2 s
  // of log at speed 4 span 0.5 s.
  const int64_t odom_at_100 = odom_ns[odom_ns.size() - 41];  // the ODOM at log time 100.0
  EXPECT_EQ(first_scan_ns, odom_at_100);
  EXPECT_NEAR(static_cast<double>(odom_ns.back() - odom_at_100) * 1e-9, 0.5, 1e-3);
  // A replayed chassis cannot be driven.
  const interfaces::ChassisMove move{0.1, 0.0, 0.0};
  EXPECT_EQ(h.call_with(chassis, interfaces::kChassisMove, move).type, tims::msg::kError);
}

TEST_F(ReplayComponentTest, MalformedLogPutsReplaysInErrorWithFileAndLine) {
  Watchdog watchdog;
  const std::string log = write("bad.log", "ODOM 0 0 0 0 0 0 1.0 h 1.0\nODOM 0 0 zero 0 0 0 1.1 h 1.1\n");
  HostUnderTest h(host(log, 1.0));
  const auto chassis = h.address_of("chassis");
  EXPECT_EQ(h.call(chassis, tims::msg::kOn).type, tims::msg::kError);
  EXPECT_NE(h.log().find(log + ":2: ODOM: theta is not a number: 'zero'"), std::string::npos) << h.log();
  EXPECT_TRUE(h.wait_status(h.address_of("gen"), tims::msg::kEnabled)) << h.log();
}

}  // namespace
}  // namespace rack::test
