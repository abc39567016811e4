// A plug-in rackd must refuse before running any of its code (rack/core/plugin_abi.h):
// built with the ABI stamp of other headers (RACK_TEST_FOREIGN_STAMP), or with none at
// all (an old plug-in). Were it loaded, its static constructor would say so on stderr
// and its entry point would register a class: plugin_class_test checks that neither
// happens and that the error names the file and both stamps.
#include <cstdio>

#include "rack/core/plugin_abi.h"
#include "rack/core/registry.h"

#ifdef RACK_TEST_FOREIGN_STAMP
RACK_PLUGIN_ABI_NOTE(RACK_TEST_FOREIGN_STAMP);
#endif

namespace {
[[maybe_unused]] const bool kRan = [] {
  std::fputs("stale plug-in: its code ran\n", stderr);
  return true;
}();
}  // namespace

extern "C" void rack_register_components(rack::ComponentRegistry& registry) {
  rack::ComponentClass c;
  c.impl = "StaleClass";
  c.class_id = 0x92;
  c.description = "must never be registered";
  c.make = [] { return std::unique_ptr<rack::Component>(); };
  registry.add(std::move(c));
}
