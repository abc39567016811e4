// What the transport's parts count and say (internal to tims): TransportStats holds
// the counters of TransportCounters as atomics, one block per transport that every
// part counts into; NetworkLog is how one network's parts (socket, authentication,
// chunks, discovery) report what they refuse or lose: counted, and said at most once a
// second per kind with the network's name and URL.
//
// Real-time contract: nothing here is RT-safe (the transport's non-RT threads).
// Thread-safety: any thread (relaxed counters: counts, no ordering with other data;
// the warnings are serialised by lcm_rx::RateLimitedWarn).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>

#include "lcm_receive.h"
#include "rack/tims/lcm_transport.h"

namespace rack::tims {

namespace lcm_detail {
inline void bump(std::atomic<uint64_t>& c, uint64_t n = 1) { c.fetch_add(n, std::memory_order_relaxed); }
}  // namespace lcm_detail

struct TransportStats {
  std::atomic<uint64_t> packets_in{0}, packets_out{0}, messages_in{0}, messages_out{0}, malformed{0}, forged{0},
      not_for_us{0}, forwarded{0}, not_available{0}, sequence_gaps{0}, lost_messages{0}, publish_errors{0},
      delivery_failed{0}, hosts_expired{0}, subscriptions_failed{0}, streams_stopped{0}, compressed_out{0},
      bytes_out{0}, wire_bytes_out{0}, auth_failed{0}, replayed{0}, malformed_lcm{0}, malformed_packet{0},
      malformed_announce{0}, malformed_discover{0}, lcm_fragments{0}, hosts_refused{0}, discovers_answered{0},
      discovers_suppressed{0};

  [[nodiscard]] TransportCounters snapshot() const noexcept;
};

class NetworkLog {
 public:
  NetworkLog(TransportStats& stats, lcm_rx::RateLimitedWarn& warn, std::string name, std::string url)
      : stats_(stats), warn_(warn), name_(std::move(name)), url_(std::move(url)) {}

  // Malformed input: counted in `malformed` and in the counter of its kind ("lcm"
  // framing, "announce", "discover", anything else a TiMS packet or message), and said
  // at most once a second per kind with the reason.
  void reject(const std::string& kind, const std::function<std::string()>& why);
  // A warning said at most once a second per `key` (the rest are counted into the next).
  template <typename MakeText>
  void warn(const std::string& key, MakeText make_text) {
    warn_(key, make_text);
  }
  [[nodiscard]] TransportStats& stats() const noexcept { return stats_; }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] const std::string& url() const noexcept { return url_; }

 private:
  TransportStats& stats_;
  lcm_rx::RateLimitedWarn& warn_;
  std::string name_;
  std::string url_;
};

}  // namespace rack::tims
