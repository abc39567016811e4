// The transport's counters and one network's refusals (lcm_transport_stats.h).
#include "lcm_transport_stats.h"

namespace rack::tims {

using lcm_detail::bump;

TransportCounters TransportStats::snapshot() const noexcept {
  const auto r = [](const std::atomic<uint64_t>& a) { return a.load(std::memory_order_relaxed); };
  TransportCounters c;
  c.packets_in = r(packets_in);
  c.packets_out = r(packets_out);
  c.messages_in = r(messages_in);
  c.messages_out = r(messages_out);
  c.malformed = r(malformed);
  c.forged = r(forged);
  c.not_for_us = r(not_for_us);
  c.forwarded = r(forwarded);
  c.not_available = r(not_available);
  c.sequence_gaps = r(sequence_gaps);
  c.lost_messages = r(lost_messages);
  c.publish_errors = r(publish_errors);
  c.delivery_failed = r(delivery_failed);
  c.hosts_expired = r(hosts_expired);
  c.subscriptions_failed = r(subscriptions_failed);
  c.streams_stopped = r(streams_stopped);
  c.compressed_out = r(compressed_out);
  c.bytes_out = r(bytes_out);
  c.wire_bytes_out = r(wire_bytes_out);
  c.auth_failed = r(auth_failed);
  c.replayed = r(replayed);
  c.malformed_lcm = r(malformed_lcm);
  c.malformed_packet = r(malformed_packet);
  c.malformed_announce = r(malformed_announce);
  c.malformed_discover = r(malformed_discover);
  c.lcm_fragments = r(lcm_fragments);
  c.hosts_refused = r(hosts_refused);
  c.discovers_answered = r(discovers_answered);
  c.discovers_suppressed = r(discovers_suppressed);
  return c;
}

void NetworkLog::reject(const std::string& kind, const std::function<std::string()>& why) {
  bump(stats_.malformed);
  bump(kind == "lcm"        ? stats_.malformed_lcm
       : kind == "announce" ? stats_.malformed_announce
       : kind == "discover" ? stats_.malformed_discover
                            : stats_.malformed_packet);
  warn_("malformed " + kind,
        [&] { return "TiMS/LCM: dropped a malformed packet on network '" + name_ + "' (" + url_ + "): " + why(); });
}

}  // namespace rack::tims
