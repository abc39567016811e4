// libFuzzer harness for the TASKS reply (GET_TASKS, rack/core/wire_tasks.h:
// decode_tasks) as `rackctl graph --live` and `rackctl alloc --live` take it from the
// network (rack/client/deployment.h: add_tasks, adopt_running, allocation_text,
// to_dot, to_json). Input: one byte (bit 0: the body is in this host's byte order;
// bit 1: the reply comes from the generator, else the monitor; bit 2: the hosts were
// found by discovery, so adopt_running takes the reply as what runs), then the reply
// body. Properties: add_tasks accepts exactly what decode_tasks accepts; an accepted
// reply gives the component a data task exactly when it says so, priorities 0..99 and
// CPUs 0..255 in ascending order; a refused one changes nothing and says why; the
// deployment made from it keeps every index in range; the JSON is JSON. Never a
// crash, a hang or an exception.
//
// Seeds: tests/fuzz/corpus/tasks/ (make_seeds.py: a periodic producer and a triggered
// consumer measured and not yet measured, both byte orders, a version-2 body, a short one).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include <nlohmann/json.hpp>

#include "fuzz_support.h"
#include "rack/client/deployment.h"
#include "rack/core/wire_tasks.h"

namespace {

rack::deploy::Deployment from_files() {
  const char* text =
      "host: fuzz\nsystem: 0\ncomponents:\n"
      "  - {name: generator, class: Generator, instance: 0, data_task: {priority: 40, period_ms: 10, cpu: 0}}\n"
      "  - {name: monitor, class: Monitor, instance: 0, data_task: {priority: 45, cpu: 0}, "
      "params: {source: generator}}\n";
  return rack::deploy::build({rack::deploy::read_host_text(text, "fuzz.yaml")});
}

rack::deploy::Deployment discovered() {
  rack::deploy::Deployment d = from_files();
  for (auto& h : d.hosts) {
    h.tasks_known = false;
    h.file = "discovery on fuzz";
    for (auto& c : h.components) {
      c.command_task.priority = -1;  // not known (cpu: -1)
      c.data_task.priority = -1;
      c.params.clear();
    }
  }
  d.flows.clear();
  return d;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const bool native = (data[0] & 1) != 0;
  const std::size_t comp = (data[0] & 2) != 0 ? 0 : 1;
  const bool adopt = (data[0] & 4) != 0;
  const std::span<const std::byte> body(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  rack::deploy::Deployment d = adopt ? discovered() : from_files();
  rack::wire::TasksReply r;
  const char* wire_bad = rack::wire::decode_tasks(body, native, r);
  rack::deploy::Live live;
  const char* bad = rack::deploy::add_tasks(d, 0, comp, body, native, live);
  FUZZ_CHECK((bad == nullptr) == (wire_bad == nullptr));
  if (bad != nullptr) {
    FUZZ_CHECK(*bad != '\0');
    for (const auto& host : live.tasks) {
      for (const auto& t : host) FUZZ_CHECK(!t.tasks_known);
    }
  } else {
    const auto& t = live.tasks.at(0).at(comp);
    FUZZ_CHECK(t.tasks_known);
    FUZZ_CHECK(t.has_data_task == (r.data_task != 0));
    FUZZ_CHECK(t.networks.size() == r.network_count);
    for (const auto* run : {&t.command, &t.data}) {
      FUZZ_CHECK(run->priority >= -1 && run->priority <= 99);
      FUZZ_CHECK(!run->measured || !run->cpus.empty());
      for (std::size_t i = 0; i < run->cpus.size(); ++i) {
        FUZZ_CHECK(run->cpus[i] >= 0 && run->cpus[i] < 256);
        FUZZ_CHECK(i == 0 || run->cpus[i] > run->cpus[i - 1]);
      }
    }
  }
  rack::deploy::match_live_flows(d, live);
  rack::deploy::adopt_running(d, live);
  FUZZ_CHECK(live.flow_state.size() == d.flows.size());
  for (const auto& g : d.cpus) {
    FUZZ_CHECK(g.host < d.hosts.size());
    for (const auto& p : g.tasks) FUZZ_CHECK(p.component < d.hosts[g.host].components.size());
  }
  (void)rack::deploy::to_dot(d, &live);
  (void)rack::deploy::allocation_text(d, &live);
  FUZZ_CHECK(nlohmann::json::accept(rack::deploy::to_json(d, &live)));
  return 0;
}
