#include "rack/components/builtin.h"

#include "chassis_sim/chassis_sim.h"
#include "generator/generator.h"
#include "ladar_sim/ladar_sim.h"
#include "mcl/mcl.h"
#include "monitor/monitor.h"
#include "odometry/odometry.h"
#include "path/path.h"
#include "pilot/pilot.h"
#include "position/position.h"
#include "evaluator/evaluator.h"
#include "modeswitch_demo/modeswitch_demo.h"
#include "probe/probe.h"
#include "replay/replay_components.h"
#include "scan2d/scan2d.h"
#include "rack/tims/address.h"

namespace rack::components {

void register_builtin(ComponentRegistry& registry) {
  namespace cls = tims::classes;
  registry.add({"Generator", cls::kGenerator, "demo: periodic sine producer",
                [] { return std::make_unique<Generator>(); }});
  registry.add({"Monitor", cls::kMonitor, "demo: subscribes to a Generator and reports what it received",
                [] { return std::make_unique<Monitor>(); }});
  registry.add({"Probe", cls::kProbe, "test: hooks fail or throw on demand",
                [] { return std::make_unique<Probe>(); }});
  registry.add({"MCL", cls::kMcl, "Monte Carlo localisation on MRPT: Scan2D + map -> pose; Position UPDATE",
                [] { return std::make_unique<Mcl>(); }});
  registry.add({"ChassisReplay", cls::kChassis, "replay: a CARMEN log or MRPT rawlog's odometry as Chassis increments",
                [] { return std::make_unique<ChassisReplay>(); }});
  registry.add({"LadarReplay", cls::kLadar, "replay: a CARMEN log or MRPT rawlog's laser scans as Ladar data",
                [] { return std::make_unique<LadarReplay>(); }});
  // The simulated robot and navigation (README: "Simulated robot and navigation").
  registry.add({"ChassisSim", cls::kChassis, "simulated drive: velocity commands, odometry with noise, true pose",
                [] { return std::make_unique<ChassisSim>(); }});
  registry.add({"LadarSim", cls::kLadar, "simulated laser scanner: ray-casts a map_server map from the true pose",
                [] { return std::make_unique<LadarSim>(); }});
  registry.add({"Odometry", cls::kOdometry, "integrates a Chassis' increments; getData(t) gives the odometry at t",
                [] { return std::make_unique<Odometry>(); }});
  registry.add({"Position", cls::kPosition, "pose = reference (UPDATE at a time) + odometry since that time",
                [] { return std::make_unique<Position>(); }});
  registry.add({"Scan2D", cls::kScan2d, "ladar scans as robot-frame points (mounting, range window, median)",
                [] { return std::make_unique<Scan2d>(); }});
  registry.add({"Path", cls::kPath, "spline path through waypoints (parameter or MAKE)",
                [] { return std::make_unique<Path>(); }});
  registry.add({"Pilot", cls::kPilot, "pure-pursuit pilot: follows a Path or goes to a destination, obstacle speed limit",
                [] { return std::make_unique<Pilot>(); }});
  registry.add({"Evaluator", cls::kEvaluator,
                "simulation: localisation error of Position and MCL against ChassisSim's true pose",
                [] { return std::make_unique<Evaluator>(); }});
  registry.add({"ModeSwitchDemo", cls::kModeSwitchDemo,
                "demo: class commands that trigger each mode-switch reason and a crash (configs/modeswitch_demo.yaml)",
                [] { return std::make_unique<ModeSwitchDemo>(); }});
}

}  // namespace rack::components
