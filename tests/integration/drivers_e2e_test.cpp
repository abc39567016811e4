// End to end, as an operator runs it: rack-devsim's CiA 402 drives and joystick as
// separate processes, rackd with configs/can_joystick.yaml (paths moved into the
// test's directory, its own LCM bus), checked with rackctl. The joystick drives the
// CAN chassis; when the stick goes away the robot stops.
#include <signal.h>

#include <gtest/gtest.h>

#include <sstream>
#include <thread>

#include "mini_json.h"
#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) {
    s.replace(at, from.size(), to);
  }
  return s;
}

class DriversEndToEndTest : public ::testing::Test {
 protected:
  DriversEndToEndTest() : watchdog_(100s, "DriversEndToEndTest") {}

  std::optional<Json> data_of(const std::string& name) {
    const RunResult r = run({RACK_RACKCTL_PATH, "--lcm", bus_.url(), "--discover-ms", "3000", "get-data", name}, 30s);
    if (r.exit_code != 0) return std::nullopt;
    return parse_json(r.out.substr(0, r.out.find('\n')));
  }

  Watchdog watchdog_;
  LcmBus bus_;
  TempDir dir_;
};

TEST_F(DriversEndToEndTest, TheJoystickDrivesTheCanChassisThroughTheSimulators) {
  const std::string can = (dir_.path() / "can0.sock").string();
  const std::string js = (dir_.path() / "js0").string();
  std::string host = read_file(std::string(RACK_CONFIGS_DIR) + "/can_joystick.yaml");
  ASSERT_NE(host.find("/tmp/rack-can0.sock"), std::string::npos);
  host = replace_all(replace_all(host, "/tmp/rack-can0.sock", can), "/tmp/rack-js0", js);
  const auto host_file = dir_.write("can_joystick.yaml", host);

  Process drives({RACK_DEVSIM_PATH, "cia402", "--socket", can}, dir_.path(), "drives");
  auto stick = std::make_unique<Process>(std::vector<std::string>{RACK_DEVSIM_PATH, "joystick", "--fifo", js,
                                                                  "--forward", "0.4", "--turn", "0.2", "--deadman", "0",
                                                                  "--period-ms", "50"},
                                         dir_.path(), "stick");
  ASSERT_TRUE(eventually([&] { return std::filesystem::exists(can) && std::filesystem::exists(js); }))
      << drives.err() << stick->err();
  const auto crash_dir = dir_.path() / "crash";
  Process rackd({RACK_RACKD_PATH, host_file.string(), "--lcm", bus_.url(), "--crash-dir", crash_dir.string()},
                dir_.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();

  // vx = 0.4 (stick) * 1.0 (vx_max) * 0.5 (speed_scale); omega = 0.2 * 1.5.
  std::optional<Json> c;
  ASSERT_TRUE(eventually([&] {
    c = data_of("chassis");
    return c && std::abs(c->at("data").at("vx").number - 0.2) < 0.005 &&
           std::abs(c->at("data").at("omega").number - 0.3) < 0.005;
  })) << (c ? "last chassis data seen: vx " + std::to_string(c->at("data").at("vx").number) : "no chassis data")
      << "\n"
      << rackd.err();
  EXPECT_EQ(c->at("data").at("active_pilot").number, static_cast<double>(0x00150000))
      << "the joystick, Joystick(0/0), is the active pilot";
  EXPECT_GT(c->at("data").at("delta_x").number, 0.0);

  // The stick goes away: the joystick goes to ERROR, stops the robot and releases it.
  stick->signal(SIGTERM);
  ASSERT_TRUE(stick->wait_exit(10s).has_value());
  stick.reset();
  ASSERT_TRUE(eventually([&] {
    c = data_of("chassis");
    return c && std::abs(c->at("data").at("vx").number) < 1e-3 && c->at("data").at("active_pilot").number == 0;
  })) << rackd.err();
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(30s), 0) << rackd.err();
  // The drivers' device I/O in their RT tasks (CAN send/receive/poll, joystick reads),
  // their device set-up in on() and the unplugging path are all legitimate: mode-switch
  // detection (on by default, warn) must not have reported anything.
  EXPECT_EQ(rackd.err().find("MODE SWITCH"), std::string::npos) << rackd.err();
  EXPECT_FALSE(std::filesystem::exists(crash_dir) && !std::filesystem::is_empty(crash_dir))
      << "a mode-switch report file was left in " << crash_dir;
}

TEST(DriversConfigTest, TheDriverHostFilesAreValid) {
  for (const char* file : {"can_joystick.yaml", "sensors.yaml"}) {
    const RunResult r = run({RACK_RACKD_PATH, "--check", std::string(RACK_CONFIGS_DIR) + "/" + file}, 30s);
    EXPECT_EQ(r.exit_code, 0) << file << ": " << r.describe();
  }
}

}  // namespace
}  // namespace rack::test
