// Access control (rack/tims/access.h) and the address texts it is configured with:
//   mode 0: the text parsers of host files and rackctl (parse_address,
//           parse_address_mask, parse_message_type) on any text; an address that
//           parses prints as a text that parses back to it;
//   mode 1: AccessControl::check() on a stream of message headers as they arrive from
//           the network or from inside the process, under rules made from the input
//           (masks, types, priorities and the positive finite rates a valid host file
//           gives), with the clock stepping by input amounts; then the denial texts,
//           report() and status_text() the executor logs.
// Input: byte 0 the mode; the rest as above.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "rack/tims/access.h"
#include "rack/tims/address.h"
#include "rack/tims/message.h"

namespace tims = rack::tims;
using rack::fuzz::FuzzInput;

namespace {

void parse_texts(FuzzInput& in) {
  const auto rest = in.rest();
  const std::string text(reinterpret_cast<const char*>(rest.data()), rest.size());
  if (const auto a = tims::parse_address(text)) {
    const std::string printed = a->str();
    const auto again = tims::parse_address(printed);
    FUZZ_CHECK(again.has_value() && again->raw() == a->raw());
  }
  if (const auto m = tims::parse_address_mask(text)) FUZZ_CHECK((m->value & ~m->mask) == 0);
  int8_t type = 0;
  (void)tims::parse_message_type(text, type);
}

void check_messages(FuzzInput& in) {
  tims::AccessConfig config;
  config.default_policy = (in.byte() & 1) != 0 ? tims::AccessDefault::kClosed : tims::AccessDefault::kOpen;
  config.sources = 1U + in.byte() % 64;
  const std::size_t rules = in.byte() % 5;
  for (std::size_t i = 0; i < rules; ++i) {
    tims::AccessRuleConfig r;
    r.name = std::string(in.byte() % 40, 'r');  // names longer than kNameLen are cut
    const std::size_t to = 1 + in.byte() % 3;
    for (std::size_t k = 0; k < to; ++k) {
      const uint32_t mask = in.take<uint32_t>();
      r.to.push_back({in.take<uint32_t>() & mask, mask});
    }
    const std::size_t from = in.byte() % 3;
    for (std::size_t k = 0; k < from; ++k) {
      const uint32_t mask = in.take<uint32_t>();
      r.from.push_back({in.take<uint32_t>() & mask, mask});
    }
    const uint8_t flags = in.byte();
    r.from_local = (flags & 1) != 0;
    r.from_network = (flags & 2) != 0;
    r.only_local = (flags & 4) != 0;
    r.any_type = (flags & 8) == 0;
    if (!r.any_type) {
      for (int k = 0; k < 3; ++k) {
        const auto t = static_cast<int8_t>(in.byte());
        r.types.set(static_cast<std::size_t>(t + 128));
        if (t <= 0) r.restricts_replies = true;
      }
    }
    r.max_priority = in.byte();
    if ((flags & 16) != 0) r.rate = 1 + in.take<uint16_t>();
    if ((flags & 32) != 0) r.burst = 1 + in.byte();
    if ((flags & 64) != 0) r.bandwidth = 1024.0 * (1 + in.take<uint16_t>());
    if ((flags & 128) != 0) r.burst_bytes = 1024.0 * (1 + in.byte());
    config.rules.push_back(r);
  }
  tims::AccessControl access(config);
  int64_t now = 1'000'000'000;
  while (!in.empty()) {
    tims::MessageHeader h{};
    h.type = in.take<int8_t>();
    h.priority = in.byte();
    h.dest = in.take<uint32_t>();
    h.src = in.take<uint32_t>();
    h.length = 16U + in.take<uint16_t>();
    const uint8_t how = in.byte();
    now += int64_t{how & 0x7F} * 1'000'000;
    const auto d = access.check(h, (how & 0x80) != 0 ? tims::MessageOrigin::kNetwork : tims::MessageOrigin::kLocal,
                                now);
    FUZZ_CHECK(d.rule >= -1 && d.rule < static_cast<int>(access.rule_count()));
    if (!d.allowed()) {
      char text[160];
      access.denial_text(d, text, sizeof text);
      FUZZ_CHECK(std::string_view(text).size() < sizeof text);
    }
  }
  (void)access.report();
  (void)access.status_text();
  (void)access.counters();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  if ((in.byte() & 1) == 0) parse_texts(in);
  else check_messages(in);
  return 0;
}
