// One place for each component class's parameter rules (Component::check_parameters
// and Parameter::Spec): the host file loader, init() and SET_PARAM apply the same
// ones. A value init() would refuse is refused by SET_PARAM with the reason, and the
// old value stays; rackd --check reports it at the parameter's line.
#include <gtest/gtest.h>

#include <string>

#include "rack/components/builtin.h"
#include "rack/core/host_config.h"
#include "test_support.h"

namespace rack {
namespace {

using test::HostUnderTest;
using test::Watchdog;
using tims::Address;
using tims::CallStatus;
namespace msg = tims::msg;
using wire::ParamKind;

const std::string kMap = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";

// Pilot, Path, MCL and Scan3D with their references given as addresses of
// components that do not run here: nothing is switched on, only parameters change.
std::string host_text() {
  return R"y(system: 0
lcm: false
heap_prefault_mib: 0
components:
  - name: pilot
    class: Pilot
    data_task: {period_ms: 50}
    params: {chassis: "Chassis(0/9)", position: "Position(0/9)", scan2d: "Scan2D(0/9)", destination: "1.5,2"}
  - name: path
    class: Path
    data_task: {period_ms: 200}
    params: {waypoints: "0,0; 4,0; 4,3"}
  - name: mcl
    class: MCL
    data_task: {priority: 0}
    params: {map: ")y" +
         kMap + R"y(", scan2d: "Scan2D(0/9)", initial_pose: "1 2 0"}
  - name: scan3d
    class: Scan3D
    params: {ladar: "Ladar(0/9)", servo: "ServoDrive(0/9)", angle_min: -0.5, angle_max: 0.5}
  - name: chassis
    class: ChassisSim
    data_task: {period_ms: 20}
)y";
}

class ParameterRulesTest : public ::testing::Test {
 protected:
  // Answer of SET_PARAM of a string value.
  HostUnderTest::Reply set_string(const std::string& component, const char* name, const char* text) {
    return host_.set_param(host_.address_of(component), name, ParamKind::kString, 0, 0.0, text);
  }
  HostUnderTest::Reply set_float(const std::string& component, const char* name, double value) {
    return host_.set_param(host_.address_of(component), name, ParamKind::kFloat, 0, value);
  }
  HostUnderTest::Reply set_int(const std::string& component, const char* name, int64_t value) {
    return host_.set_param(host_.address_of(component), name, ParamKind::kInt, value);
  }
  std::string value_of(const std::string& component, const char* name) {
    const Parameter* p = host_.executor().find(component)->parameters().find(name);
    return p == nullptr ? "?" : p->value_text();
  }
  // Expects an ERROR reply naming the parameter and `reason`, and the old value kept.
  void expect_refused(const HostUnderTest::Reply& r, const std::string& component, const char* name,
                      const std::string& old_value, const char* reason) {
    ASSERT_EQ(r.status, CallStatus::kOk);
    EXPECT_EQ(r.type, msg::kError) << component << "." << name << " was accepted";
    EXPECT_NE(r.error_text().find(name), std::string::npos) << r.error_text();
    EXPECT_NE(r.error_text().find(reason), std::string::npos) << r.error_text();
    EXPECT_EQ(value_of(component, name), old_value);
  }

  Watchdog dog_;
  HostUnderTest host_{host_text()};
};

TEST_F(ParameterRulesTest, PilotRefusesAModeAndADestinationInitWouldRefuse) {
  expect_refused(set_string("pilot", "mode", "fly"), "pilot", "mode", "path", "not one of the allowed values");
  expect_refused(set_string("pilot", "destination", "six,eight"), "pilot", "destination", "1.5,2", "not \"x,y\"");
  expect_refused(set_string("pilot", "destination", "1,nan"), "pilot", "destination", "1.5,2", "not \"x,y\"");
  // Valid values still pass.
  EXPECT_EQ(set_string("pilot", "mode", "hold").type, msg::kOk);
  EXPECT_EQ(set_string("pilot", "destination", "3, 4").type, msg::kOk);
  EXPECT_EQ(value_of("pilot", "destination"), "3, 4");
  EXPECT_EQ(set_string("pilot", "destination", "").type, msg::kOk);
}

TEST_F(ParameterRulesTest, PathRefusesAWaypointListItCannotMake) {
  const std::string old = value_of("path", "waypoints");
  expect_refused(set_string("path", "waypoints", "0,0; x,1"), "path", "waypoints", old, "item 2");
  expect_refused(set_string("path", "waypoints", "0,0"), "path", "waypoints", old, "waypoints");
  EXPECT_EQ(set_string("path", "waypoints", "0,0; 2,0; 2,2").type, msg::kOk);
}

TEST_F(ParameterRulesTest, MclRefusesAPoseAndOptionsItsFilterWouldRefuse) {
  expect_refused(set_string("mcl", "initial_pose", "1 2"), "mcl", "initial_pose", "1 2 0", "x y phi");
  // Cross-parameter rules of the filter (mcl::check_options), with the candidate in place.
  expect_refused(set_int("mcl", "particles_min", 5000), "mcl", "particles_min", "100",
                 "particles_max must be at least");
  expect_refused(set_float("mcl", "alpha_slow", 0.5), "mcl", "alpha_slow", value_of("mcl", "alpha_slow"),
                 "alpha_slow < alpha_fast");
  // The map is loaded by init() only: changing it at run time is refused.
  expect_refused(set_string("mcl", "map", "/nonexistent.yaml"), "mcl", "map", kMap, "read at start only");
  EXPECT_EQ(set_int("mcl", "particles_min", 500).type, msg::kOk);
}

TEST_F(ParameterRulesTest, Scan3dRefusesAnglesAndPipelineOptionsInitWouldRefuse) {
  expect_refused(set_float("scan3d", "angle_min", 0.7), "scan3d", "angle_min", "-0.5", "angle_max must be above");
  expect_refused(set_float("scan3d", "voxel_size", 0.0005), "scan3d", "voxel_size", value_of("scan3d", "voxel_size"),
                 "voxel_size below 1 mm");
  expect_refused(set_string("scan3d", "mode", "roll"), "scan3d", "mode", "pitch", "read at start only");
  EXPECT_EQ(set_float("scan3d", "angle_min", -0.7).type, msg::kOk);
}

TEST_F(ParameterRulesTest, ChassisSimRefusesStartOnlyParameters) {
  expect_refused(set_string("chassis", "map", "/etc/passwd"), "chassis", "map", "", "read at start only");
  expect_refused(set_float("chassis", "initial_x", 3.0), "chassis", "initial_x", value_of("chassis", "initial_x"),
                 "read at start only");
}

// The same rules in the host file: rackd --check reports them at the parameter's line.
class ParameterRulesHostFileTest : public ::testing::Test {
 protected:
  ParameterRulesHostFileTest() {
    components::register_builtin(registry_);
    caps_.online_cpus = {0, 1};
  }
  void expect_error(const std::string& text, int line, const std::string& words) {
    const LoadResult r = load_host_text(text, "host.yaml", registry_, caps_);
    EXPECT_EQ(r.host, nullptr);
    std::string all;
    bool found = false;
    for (const auto& e : r.errors) {
      all += e.str() + "\n";
      found = found || (e.line == line && e.column > 0 && e.message.find(words) != std::string::npos);
    }
    EXPECT_TRUE(found) << "expected line " << line << ": " << words << "\ngot:\n" << all;
  }
  ComponentRegistry registry_;
  rt::RtCapabilities caps_;
};

TEST_F(ParameterRulesHostFileTest, PilotModeAndDestinationAreCheckedAtTheirLines) {
  const std::string head = R"y(lcm: false
components:
  - name: pilot
    class: Pilot
    data_task: {period_ms: 50}
    params:
      chassis: "Chassis(0/9)"
      position: "Position(0/9)"
      scan2d: "Scan2D(0/9)"
)y";
  expect_error(head + "      mode: fly\n", 10, "must be one of path, hold");
  expect_error(head + "      destination: \"six,eight\"\n", 10, "parameter 'destination': not \"x,y\"");
}

TEST_F(ParameterRulesHostFileTest, PathAndMclRulesAreCheckedAtTheirLines) {
  expect_error(R"y(lcm: false
components:
  - name: path
    class: Path
    data_task: {period_ms: 200}
    params:
      closed: true
      waypoints: "0,0; 1,1; oops"
)y",
               8, "parameter 'waypoints': item 3");
  expect_error(R"y(lcm: false
components:
  - name: mcl
    class: MCL
    params:
      map: x.yaml
      scan2d: "Scan2D(0/9)"
      particles_min: 300
      particles_max: 200
)y",
               9, "particles_max must be at least particles_min");
}

}  // namespace
}  // namespace rack
