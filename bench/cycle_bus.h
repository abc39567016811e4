// The measured cycle's message path that bench_trace and bench_clock share.
//
// Not RT code to set up (the constructor registers the mailbox); the cycle's send to
// `sink` and receive into `buffer` are the RT path being measured.
#pragma once

#include <array>
#include <cstddef>

#include "rack/tims/address.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"

namespace rack::bench {

// A local router with one sink mailbox, a 64-byte sample sent to it and read back into `buffer` each cycle.
struct CycleBus {
  tims::Router router{0};
  tims::Mailbox sink{tims::Address::make(0, tims::classes::kTool, 2, 1), 8, 256};
  tims::Address self = tims::Address::make(0, tims::classes::kTool, 1, 1);
  std::array<std::byte, 64> sample{};
  alignas(8) std::array<std::byte, 256> buffer{};
  CycleBus() { router.add(sink); }
  ~CycleBus() { router.remove(sink.address()); }
  CycleBus(const CycleBus&) = delete;
  CycleBus& operator=(const CycleBus&) = delete;
};

}  // namespace rack::bench
