// TiMS over LCM: the only place that links LCM (DESIGN.md).
//
// Two non-RT threads per transport: a receiver (polls LCM's descriptor, validates
// each packet, hands it to the local router) and a sender (drains the router's
// uplink mailbox and publishes). RT tasks never touch the network: they queue into
// the uplink mailbox (PI-locked bookkeeping, copy outside the lock) and go on.
//
// Channels: "TIMS" (tims_packet), "TIMS_ANNOUNCE" (host_announce), "TIMS_DISCOVER".
//
// Real-time contract: nothing here is RT-safe; everything is set-up or runs in the
// transport's own non-RT threads. Thread-safety: hosts(), counters() and
// set_announcement() may be called from any non-RT thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"

namespace rack::tims {

inline constexpr const char* kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

struct ComponentInfo {
  Address address;
  std::string name;
  std::string impl;
};

struct HostInfo {
  std::string host;
  uint8_t system = 0;
  int32_t pid = 0;
  Address executor;
  std::vector<ComponentInfo> components;
  int64_t last_seen_ns = 0;  // CLOCK_MONOTONIC of the receiver
};

struct TransportCounters {
  uint64_t packets_in = 0;
  uint64_t packets_out = 0;
  uint64_t malformed = 0;       // dropped: not a TiMS packet, bad header, bad length
  uint64_t not_for_us = 0;      // valid, for a mailbox not on this host
  uint64_t publish_errors = 0;
  uint64_t delivery_failed = 0; // local mailbox refused (full, too large)
};

struct LcmTransportConfig {
  std::string url = kDefaultLcmUrl;
  uint32_t uplink_slots = 256;
  uint32_t uplink_slot_size = 64 * 1024;
  int64_t announce_period_ns = 1'000'000'000;  // 0: only at start, on change, on request
  // Where warnings go (malformed packets, publish errors), rate-limited by the
  // transport. Default: stderr.
  std::function<void(const std::string&)> warn;
};

class LcmTransport {
 public:
  // Joins the LCM network and makes the uplink mailbox (its address is on the tool
  // system, never routed to). Throws std::runtime_error naming the URL on failure.
  LcmTransport(Router& router, LcmTransportConfig config);
  ~LcmTransport();
  LcmTransport(const LcmTransport&) = delete;
  LcmTransport& operator=(const LcmTransport&) = delete;

  void start();  // starts the two threads and connects the router's uplink
  void stop();   // idempotent

  // What this host announces (executors only). Publishes at once when running.
  void set_announcement(HostInfo info);
  // Asks every host to announce itself.
  void request_discovery();
  // Hosts heard from (announcements), newest first per host.
  [[nodiscard]] std::vector<HostInfo> hosts() const;

  [[nodiscard]] TransportCounters counters() const noexcept;
  [[nodiscard]] const std::string& url() const noexcept { return config_.url; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  Router& router_;
  LcmTransportConfig config_;
};

}  // namespace rack::tims
