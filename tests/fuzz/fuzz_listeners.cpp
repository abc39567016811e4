// libFuzzer harness for the LISTENERS reply (GET_LISTENERS, rack/core/wire.h:
// decode_listeners) as `rackctl graph --live` and rack-gui's live graph take it from
// the network (rack/client/deployment.h: add_listeners, match_live_flows, to_dot,
// to_json). Input: one byte (bit 0: the body is in this host's byte order; bit 1: the
// reply comes from the generator, else the monitor), then the reply body. Properties:
// add_listeners accepts exactly what decode_listeners accepts; an accepted reply adds
// at most 32 live flows, each from the component asked and with a period >= 0; a
// refused one adds none and says why; every flow's match is an index in range; the
// JSON is JSON. Never a crash, a hang or an exception.
//
// Seeds: tests/fuzz/corpus/listeners/ (make_seeds.py: none, one, two and 32
// listeners, in both byte orders; a wrong size).
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include <nlohmann/json.hpp>

#include "fuzz_support.h"
#include "rack/client/deployment.h"
#include "rack/core/wire.h"

namespace {

const rack::deploy::Deployment& deployment() {
  static const rack::deploy::Deployment d = [] {
    const char* text =
        "host: fuzz\nsystem: 0\ncomponents:\n"
        "  - {name: generator, class: Generator, instance: 0, data_task: {period_ms: 10}}\n"
        "  - {name: monitor, class: Monitor, instance: 0, params: {source: generator}}\n";
    return rack::deploy::build({rack::deploy::read_host_text(text, "fuzz.yaml")});
  }();
  return d;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const bool native = (data[0] & 1) != 0;
  const std::size_t comp = (data[0] & 2) != 0 ? 0 : 1;
  const std::span<const std::byte> body(reinterpret_cast<const std::byte*>(data + 1), size - 1);
  const rack::deploy::Deployment& d = deployment();
  rack::wire::ListenersReply r;
  const char* wire_bad = rack::wire::decode_listeners(body, native, r);
  rack::deploy::Live live;
  const char* bad = rack::deploy::add_listeners(d, 0, comp, body, native, live);
  FUZZ_CHECK((bad == nullptr) == (wire_bad == nullptr));
  if (bad != nullptr) {
    FUZZ_CHECK(*bad != '\0');
    FUZZ_CHECK(live.flows.empty());
  } else {
    FUZZ_CHECK(live.flows.size() == r.count);
    FUZZ_CHECK(live.flows.size() <= rack::wire::kMaxListenerRecords);
    for (const auto& f : live.flows) {
      FUZZ_CHECK(f.producer_host == 0 && f.producer == comp);
      FUZZ_CHECK(f.period_ns >= 0);
      FUZZ_CHECK(f.listener != 0);
    }
  }
  rack::deploy::match_live_flows(d, live);
  FUZZ_CHECK(live.flow_state.size() == d.flows.size());
  for (const auto& f : live.flows) {
    FUZZ_CHECK(f.flow == rack::deploy::kNone || f.flow < d.flows.size());
    FUZZ_CHECK(f.consumer == rack::deploy::kNone ||
               (f.consumer_host < d.hosts.size() && f.consumer < d.hosts[f.consumer_host].components.size()));
    FUZZ_CHECK(!rack::deploy::listener_text(d, f).empty());
  }
  (void)rack::deploy::to_dot(d, &live);
  FUZZ_CHECK(nlohmann::json::accept(rack::deploy::to_json(d, &live)));
  return 0;
}
