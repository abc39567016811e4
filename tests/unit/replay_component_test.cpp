// ChassisReplay and LadarReplay in a real executor: a CARMEN log played as Chassis
// increments and Ladar scans on one clock, at a chosen speed; a malformed log puts the
// replay components in ERROR with the file and line while the rest runs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <vector>

#include "rack/interfaces/robot.h"
#include "scan2d/scan2d.h"
#include "test_support.h"

namespace rack::test {
namespace {

using interfaces::ChassisData;
using interfaces::LadarData;
using interfaces::Scan2dData;

// The odometry pose of write_interleaved_log() at log time t (s): a quarter circle of
// radius 1 m at 0.5 rad/s from t = 100 on, standing before.
struct LogPose {
  double x, y, phi;
};
LogPose circle_at(double t) {
  const double a = t <= 100.0 ? 0.0 : 0.5 * (t - 100.0);
  return {std::sin(a), 1.0 - std::cos(a), a};
}
// The same, interpolated linearly between the log's ODOM records (every 50 ms from
// t = 100), as Scan2D must give it at a scan's time.
LogPose odom_between_records(double t) {
  const double k = std::floor((t - 100.0) / 0.05 + 1e-9);
  const double t0 = 100.0 + k * 0.05, t1 = t0 + 0.05;
  const LogPose a = circle_at(t0), b = circle_at(t1);
  const double f = (t - t0) / 0.05;
  return {a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.phi + f * (b.phi - a.phi)};
}

class ReplayComponentTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("rack_replay_test_" + std::to_string(::getpid()) + "_" +
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
  // ODOM every 50 ms (100.00 .. 102.00) and 20 scans between them (100.0125 +
  // k * 0.1 s), so that every scan's odometry is an interpolation; one ODOM at 99.0
  // starts the clock a second early (time for the subscriptions when not paced).
  std::string write_interleaved_log() {
    std::ostringstream out;
    out.precision(10);
    out << "ODOM 0 0 0 0 0 0 99.0 host 99.0\n";
    for (int i = 0; i <= 40; ++i) {
      const double t = 100.0 + i * 0.05;
      const LogPose p = circle_at(t);
      out << "ODOM " << p.x << " " << p.y << " " << p.phi << " 0.5 0.5 0 " << t << " host " << t << "\n";
      if (i % 2 == 0 && i < 40) {
        const double ts = t + 0.0125;
        out << "ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 7";
        for (int b = 0; b < 7; ++b) out << " " << (1.0 + b);
        out << " 0 0 0 0 0 0 0 0.5 0.5 0 0 0 " << ts << " host " << ts << "\n";
      }
    }
    return write("interleaved.log", out.str());
  }
  // ChassisReplay, LadarReplay, Odometry and Scan2D (with odometry), at `speed`;
  // speed 0 paces the ladar on scan2d.
  static std::string pipeline_host(const std::string& log, double speed) {
    std::ostringstream y;
    const std::string pace = speed > 0 ? "" : ", pace: scan2d";
    y << "lcm: false\ncomponents:\n"
         "  - name: chassis\n    class: ChassisReplay\n    data_task: {priority: 40, period_ms: 2, ring: 200}\n"
         "    params: {log: \""
      << log << "\", speed: " << speed << "}\n"
      << "  - name: ladar\n    class: LadarReplay\n    data_task: {priority: 40, period_ms: 2, ring: 100}\n"
         "    params: {log: \""
      << log << "\", speed: " << speed << pace << "}\n"
      << "  - name: odometry\n    class: Odometry\n    data_task: {priority: 39, ring: 500}\n"
         "    params: {chassis: chassis, silence_ms: 5000}\n"
         "  - name: scan2d\n    class: Scan2D\n    data_task: {priority: 38, ring: 100, input_slots: 128}\n"
         "    params: {ladar: ladar, odometry: odometry, silence_ms: 5000}\n";
    return y.str();
  }
  // Plays the interleaved log through Scan2D at `speed` and returns the odometry each
  // scan carries, by scan time (read back from Scan2D's ring once all 20 played).
  std::map<int64_t, LogPose> scan_odometry(const std::string& log, double speed,
                                           components::Scan2d::OdometryCounts& counts) {
    HostUnderTest h(pipeline_host(log, speed));
    const auto scan2d = h.address_of("scan2d");
    EXPECT_EQ(h.call(scan2d, tims::msg::kOn).type, tims::msg::kOk) << h.log();
    EXPECT_TRUE(eventually([&] { return h.stats(scan2d).published >= 20; }, std::chrono::seconds(20)))
        << "speed " << speed << ": " << h.stats(scan2d).published << " scans\n"
        << h.log();
    std::map<int64_t, LogPose> out;
    auto s = std::make_unique<Scan2dData>();
    for (int k = 0; k < 20; ++k) {
      wire::GetDataRequest get;
      get.time_ns = 100'012'500'000 + k * 100'000'000LL;  // the scan's log time, in ns
      const auto r = h.call_with(scan2d, tims::msg::kGetData, get);
      wire::SampleHeader sh{};
      if (r.type != tims::msg::kData || r.body.size() != sizeof sh + sizeof(Scan2dData)) {
        ADD_FAILURE() << "speed " << speed << ": no scan at " << get.time_ns;
        continue;
      }
      std::memcpy(&sh, r.body.data(), sizeof sh);  // one process: native byte order
      std::memcpy(s.get(), r.body.data() + sizeof sh, sizeof(Scan2dData));
      EXPECT_EQ(sh.time_ns, get.time_ns) << "speed " << speed << ": scans carry the log's time";
      EXPECT_EQ(s->odometry_valid, 1) << "speed " << speed << ", scan " << k;
      out[sh.time_ns] = {s->odometry_x, s->odometry_y, s->odometry_phi};
    }
    counts = dynamic_cast<components::Scan2d*>(h.executor().find("scan2d"))->odometry_counts();
    return out;
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
  // Samples carry the log's own time at any speed: the first scan and the ODOM at log
  // time 100.0 are stamped 100 s; the last ODOM 102 s.
  const int64_t odom_at_100 = odom_ns[odom_ns.size() - 41];  // the ODOM at log time 100.0
  EXPECT_EQ(odom_at_100, 100 * rt::kNsPerSec);
  EXPECT_EQ(first_scan_ns, odom_at_100);
  EXPECT_EQ(odom_ns.back(), 102 * rt::kNsPerSec);
  // A replayed chassis cannot be driven.
  const interfaces::ChassisMove move{0.1, 0.0, 0.0};
  EXPECT_EQ(h.call_with(chassis, interfaces::kChassisMove, move).type, tims::msg::kError);
}

// The race of issue 18: Scan2D took the odometry sample before a scan's time and
// extrapolated it (1-22 % of scan pairs with a wrong increment, more above speed 1).
// Now each scan's odometry is the log's, interpolated at the scan's own time, at
// speed 1, at speed 50 and as fast as paced (speed 0), and the three agree exactly.
TEST_F(ReplayComponentTest, ScansCarryTheLogsOdometryAtTheirTimeAtAnySpeed) {
  Watchdog watchdog(std::chrono::seconds(90));
  const std::string log = write_interleaved_log();
  std::map<double, std::map<int64_t, LogPose>> runs;
  for (const double speed : {1.0, 50.0, 0.0}) {
    components::Scan2d::OdometryCounts counts;
    runs[speed] = scan_odometry(log, speed, counts);
    EXPECT_EQ(counts.missing, 0U) << "speed " << speed;
    EXPECT_EQ(counts.interpolated, 20U) << "speed " << speed;
    // Consecutive scan pairs whose odometry increment is not the log's: 0.
    int wrong = 0;
    const std::map<int64_t, LogPose>& got = runs[speed];
    for (auto it = got.begin(); it != got.end() && std::next(it) != got.end(); ++it) {
      const auto next = std::next(it);
      const LogPose a = odom_between_records(static_cast<double>(it->first) * 1e-9);
      const LogPose b = odom_between_records(static_cast<double>(next->first) * 1e-9);
      const double dx = (next->second.x - it->second.x) - (b.x - a.x);
      const double dy = (next->second.y - it->second.y) - (b.y - a.y);
      const double dphi = (next->second.phi - it->second.phi) - (b.phi - a.phi);
      if (std::hypot(dx, dy) > 1e-6 || std::abs(dphi) > 1e-6) ++wrong;
    }
    EXPECT_EQ(wrong, 0) << "speed " << speed << ": scan pairs with a wrong odometry increment";
    for (const auto& [t, p] : got) {
      const LogPose e = odom_between_records(static_cast<double>(t) * 1e-9);
      EXPECT_NEAR(p.x, e.x, 1e-6) << "speed " << speed << " at " << t;
      EXPECT_NEAR(p.y, e.y, 1e-6) << "speed " << speed << " at " << t;
      EXPECT_NEAR(p.phi, e.phi, 1e-6) << "speed " << speed << " at " << t;
    }
  }
  // The same odometry at every speed (bit for bit: the same samples, the same sums).
  for (const double speed : {50.0, 0.0}) {
    ASSERT_EQ(runs[speed].size(), runs[1.0].size());
    for (const auto& [t, p] : runs[1.0]) {
      const LogPose& q = runs[speed].at(t);
      EXPECT_EQ(q.x, p.x);
      EXPECT_EQ(q.y, p.y);
      EXPECT_EQ(q.phi, p.phi);
    }
  }
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
