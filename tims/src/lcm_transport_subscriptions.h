// The data flows that cross to other hosts (internal to tims): subscriptions of local
// consumers to remote producers (GET_CONT_DATA sent from here) and streams of local
// producers to remote listeners (DATA sent from here), remembered as they leave this
// host and ended when the other host is lost: every local consumer of a lost producer
// gets an ERROR in the producer's name (as a producer going OFF sends; it goes to ERROR
// and re-subscribes by its own retry), every local producer streaming to a lost host a
// STOP_CONT_DATA (or it would stream into the void for good). Part of Discovery.
//
// Real-time contract: nothing here is RT-safe. Thread-safety: none of its own; used
// under Discovery's table lock.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "lcm_transport_stats.h"
#include "rack/tims/router.h"

namespace rack::tims {

class RemoteSubscriptions {
 public:
  // At most this many subscriptions and streams are remembered each (bounded).
  static constexpr std::size_t kMaxTracked = 4096;

  // `control`: the transport's own mailbox, the source of its STOP_CONT_DATA.
  RemoteSubscriptions(Router& router, Address control, TransportStats& stats)
      : router_(router), control_(control), stats_(stats) {}

  // A message leaving this host: GET_CONT_DATA and STOP_CONT_DATA start and end a
  // subscription, DATA of a local producer is a stream.
  void track(const MessageHeader& h, std::span<const std::byte> body);
  // An ERROR from `producer` to `listener` ended that subscription.
  void forget(uint32_t producer, uint32_t listener);
  // `lost` is gone (`why` goes into the ERROR's text): its subscriptions are failed and
  // the streams to it stopped (counted: subscriptions_failed, streams_stopped).
  void end(const HostInfo& lost, const std::string& why);

 private:
  struct Subscription {
    uint32_t producer = 0;  // component address of the remote producer
    uint32_t listener = 0;  // local mailbox that receives the samples
    uint8_t priority = 0;
  };

  Router& router_;
  const Address control_;
  TransportStats& stats_;
  std::vector<Subscription> subscriptions_;
  // (local producer component << 32 | remote listener mailbox) -> when last seen.
  std::unordered_map<uint64_t, int64_t> streams_;
};

}  // namespace rack::tims
