// The component classes a rackd knows, as the deployment view needs them
// (rack::deploy::ClassInfo): learnt from `rackd --list-classes --json`, a child
// process, so that rackctl and rack-gui know every built-in class's component
// references without linking the executor. Not RT code (tools).
#pragma once

#include <string>
#include <vector>

#include "rack/client/deployment.h"

namespace rack::tools {

// The rackd program beside this one (installed: both in bin/; build tree: tools/),
// else "rackd" (on PATH).
[[nodiscard]] std::string rackd_beside_me();

// Parses `rackd --list-classes --json`'s output; false and `why` when it is not that.
[[nodiscard]] bool parse_class_list(const std::string& json_text, std::vector<rack::deploy::ClassInfo>& out,
                                    std::string& why);

// Runs `rackd --list-classes --json [HOSTFILE ...]` (killed after `timeout_ms`) and
// parses it. With `host_files`, rackd also searches their `plugins:` directories and
// describes the plug-in classes they name in full (their component references and
// class names), which a rackd alone knows only by their manifests.
[[nodiscard]] bool classes_from_rackd(const std::string& rackd, std::vector<rack::deploy::ClassInfo>& out,
                                      std::string& why, int timeout_ms = 10000,
                                      const std::vector<std::string>& host_files = {});

}  // namespace rack::tools
