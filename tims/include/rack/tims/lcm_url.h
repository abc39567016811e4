// LCM URLs, checked before anything is opened: the one parser of an LCM URL that the
// host file loader (rackd --check), rackd's --lcm and the tools use, so that a URL
// LCM 1.3.1 would refuse (or, worse, half accept: it only warns about a bad option
// and goes on with its default) is refused with a reason first.
//
//   provider://network?key=value&key=value
//
//   udpm://GROUP:PORT?ttl=N&recv_buf_size=BYTES   UDP multicast (LCM's default):
//       GROUP an IPv4 multicast address (224.0.0.0/4; empty: 239.255.76.67),
//       PORT 1..65535 (default 7667), ttl 0..255, recv_buf_size 1..2147483647
//   mpudpm://GROUP:PORT?ttl=N&recv_buf_size=BYTES  the same keys, several ports
//   memq://                                       inside this process (no network, no keys)
//   tcpq://HOST:PORT                              LCM's TCP queue server
//   file://PATH?mode=r|w|a&speed=X&start_timestamp=T   an LCM log
//
// Every value is checked (digits only, in range, no sign, no repeat of a key); an
// unknown provider or key, spaces, control characters or more than kMaxLcmUrlLength
// bytes are refused.
//
// Real-time contract: not RT-safe (allocates). Thread-safe (pure).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace rack::tims {

inline constexpr std::size_t kMaxLcmUrlLength = 256;

struct LcmUrl {
  std::string provider;       // udpm, mpudpm, memq, tcpq, file
  std::string network;        // between "://" and "?" (udpm: "GROUP:PORT" as written)
  uint32_t group = 0;         // udpm/mpudpm: the multicast group, host byte order
  uint16_t port = 0;          // udpm/mpudpm/tcpq
  int ttl = 0;                // udpm/mpudpm (LCM's default 0)
  int64_t recv_buf_size = 0;  // udpm/mpudpm: 0 when not given (the kernel's default)
};

struct LcmUrlResult {
  LcmUrl url;
  std::string error;  // empty: valid; otherwise why not ("port 99999 is outside 1..65535")
  [[nodiscard]] bool ok() const noexcept { return error.empty(); }
};

[[nodiscard]] LcmUrlResult parse_lcm_url(std::string_view text);

}  // namespace rack::tims
