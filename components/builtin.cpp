#include "rack/components/builtin.h"

#include "generator/generator.h"
#include "mcl/mcl.h"
#include "monitor/monitor.h"
#include "probe/probe.h"
#include "replay/replay_components.h"
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
}

}  // namespace rack::components
