// libFuzzer harness for the deployment reader (rack/client/deployment.h,
// client/src/deployment.cpp), a decoder of outside input: `rackctl graph` / `alloc`
// and rack-gui's configuration view read host files with it. Any bytes go to
// read_host_text(), twice (a second file, so flows between hosts and duplicate
// addresses are built), then build() and every output. It must never crash, hang,
// throw or recurse without bound; every error names the file with a line >= 0, and the
// JSON it writes is JSON.
//
// Seeds: tests/fuzz/corpus/deployment/ (configs/two_robots/, flow and block styles,
// cpus forms, anchors and aliases).
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "rack/client/deployment.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  rack::deploy::Host a = rack::deploy::read_host_text(text, "fuzz.yaml");
  for (const auto& e : a.errors) {
    if (e.file != "fuzz.yaml" || e.line < 0 || e.column < 0 || e.message.empty()) __builtin_trap();
  }
  rack::deploy::Host b = rack::deploy::read_host_text(text, "copy.yaml");
  const std::vector<rack::deploy::ClassInfo> classes{{"Monitor", "Monitor", true, {"source"}}};
  const rack::deploy::Deployment d = rack::deploy::build({std::move(a), std::move(b)},
                                                         size % 2 == 0 ? &classes : nullptr);
  for (const auto& f : d.flows) {
    if (f.consumer_host >= d.hosts.size() || f.consumer >= d.hosts[f.consumer_host].components.size()) __builtin_trap();
    if (f.producer != rack::deploy::kNone &&
        (f.producer_host >= d.hosts.size() || f.producer >= d.hosts[f.producer_host].components.size())) {
      __builtin_trap();
    }
  }
  (void)rack::deploy::to_dot(d);
  (void)rack::deploy::allocation_text(d);
  if (!nlohmann::json::accept(rack::deploy::to_json(d))) __builtin_trap();
  return 0;
}
