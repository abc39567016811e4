#include "rack/components/builtin.h"

#include "generator/generator.h"
#include "monitor/monitor.h"
#include "modeswitch_demo/modeswitch_demo.h"
#include "probe/probe.h"
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
  registry.add({"ModeSwitchDemo", cls::kModeSwitchDemo,
                "demo: class commands that trigger each mode-switch reason and a crash (configs/modeswitch_demo.yaml)",
                [] { return std::make_unique<ModeSwitchDemo>(); }});
}

}  // namespace rack::components
