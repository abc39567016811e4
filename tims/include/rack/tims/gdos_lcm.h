// GDOS on LCM: how a host publishes its formatted log records and how tools (the
// `gdos` viewer) receive them. The LCM types are in tims/lcm/rack_gdos.lcm.
//
// Receiving (the subscriber, and the publisher's check for listeners): on a udpm://
// network from a socket of its own, LCM's framing parsed by bounds-checked code and
// LCM fragments refused (LCM 1.3's reassembly trusts its input), every message decoded
// by total decoders (lcm-gen's throw on a string length of 0). What is refused is
// counted (GdosSubscriberCounters, GdosPublisherCounters::refused) and, in the
// subscriber, warned at most once a second per kind.
//
// A host publishes batches (rack_lcm.gdos_batch) on its own LCM instance, by
// default on the TiMS URL, channel "RACK_GDOS". Each record carries the host, the
// component's address and name, the level, the host time and a sequence number per
// publishing process (gaps are losses on the network). A viewer announces itself on
// "RACK_GDOS_LISTENER" once a second, so a host can stop copying its log to stderr
// while somebody listens (gdos.stderr: auto).
//
// Authenticated: with a key file (the host's keyed network's, rack/tims/link_auth.h)
// every batch carries the same MAC trailer as TiMS packets; a subscriber with the key
// drops and counts batches and announcements that do not verify (auth_failed,
// replayed). A subscriber without a key still shows signed batches (the text is not
// secret), unverified, and says so once. Listener announcements are not signed (they
// only switch a host's stderr copy).
//
// Real-time contract: nothing here is RT-safe; the publisher runs in the host's
// GDOS thread, the subscriber in a tool. Thread-safety: one thread per object,
// except GdosPublisher::counters() (any thread).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>

namespace rack::tims {

inline constexpr const char* kGdosChannel = "RACK_GDOS";
inline constexpr const char* kGdosListenerChannel = "RACK_GDOS_LISTENER";

// One record as tools see it.
struct GdosRecord {
  std::string host;
  int32_t pid = 0;
  uint32_t source = 0;  // TiMS address (bits)
  std::string name;     // component name ("" if unknown)
  uint8_t level = 0;    // 0 print .. 4 detail
  int64_t time_ns = 0;  // host clock
  uint64_t sequence = 0;
  uint32_t dropped_before = 0;
  std::string text;
};

struct GdosPublisherConfig {
  std::string url;  // LCM URL
  std::string channel = kGdosChannel;
  std::string host;  // host name in every batch
  int32_t pid = 0;
  std::size_t max_batch_bytes = 16 * 1024;  // well below LCM's fragmentation size
  std::string key_file;                     // "": batches unsigned
};

struct GdosPublisherCounters {
  uint64_t records = 0;
  uint64_t batches = 0;
  uint64_t publish_errors = 0;
  uint64_t refused =
      0;  // datagrams the listener check refused: not LCM, LCM fragments, listener messages that do not decode
};

class GdosPublisher {
 public:
  // Joins the LCM network. Throws std::runtime_error naming the URL on failure.
  explicit GdosPublisher(GdosPublisherConfig config);
  ~GdosPublisher();
  GdosPublisher(const GdosPublisher&) = delete;
  GdosPublisher& operator=(const GdosPublisher&) = delete;

  // Adds a record to the current batch; publishes the batch when it is full.
  void add(uint32_t source, std::string_view name, uint8_t level, int64_t time_ns, uint64_t sequence,
           uint32_t dropped_before, std::string_view text);
  void flush();  // publishes what is batched
  // Reads pending listener announcements (non-blocking) and says whether a viewer
  // announced itself within the last `within_ns`.
  [[nodiscard]] bool listener_present(int64_t within_ns);
  [[nodiscard]] GdosPublisherCounters counters() const noexcept;
  [[nodiscard]] const std::string& url() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct GdosSubscriberCounters {
  uint64_t batches = 0;
  uint64_t records = 0;
  uint64_t malformed = 0;          // undecodable batches on the channel (string lengths, counts, truncation)
  uint64_t bad_announcements = 0;  // TIMS_ANNOUNCE that do not decode (names are then not learnt)
  uint64_t bad_datagrams = 0;      // not LCM: short, wrong magic, channel name unterminated or too long
  uint64_t lcm_fragments = 0;      // LCM fragments (messages above 64 KB), refused: never sent by rackd
  uint64_t lost = 0;               // sequence gaps (records lost between a host and us)
  uint64_t auth_failed = 0;        // with a key: batches/announcements unsigned, unknown key, bad MAC
  uint64_t replayed = 0;           // with a key: seen before, or outside the time window
};

class GdosSubscriber {
 public:
  // Joins the LCM network and subscribes to `channel` and to the TiMS announcements
  // (names of components). With `announce`, says once a second that it listens.
  // Throws std::runtime_error naming the URL on failure.
  // `key_file`: verify batches and announcements with it (throws std::runtime_error
  // with the reason when the file is refused).
  GdosSubscriber(const std::string& url, const std::string& channel, bool announce, std::string name,
                 const std::string& key_file = "");
  ~GdosSubscriber();
  GdosSubscriber(const GdosSubscriber&) = delete;
  GdosSubscriber& operator=(const GdosSubscriber&) = delete;

  // Waits up to `timeout_ms` for traffic and hands every record received to `sink`
  // (in arrival order; a host's records in its order). Returns the records handled.
  std::size_t poll(int timeout_ms, const std::function<void(const GdosRecord&)>& sink);
  // Handles one datagram in LCM's framing as if it had arrived on the socket (the
  // receive path without the socket: fuzz harnesses). Never throws; refusals are
  // counted and warned as on the socket.
  void handle_datagram(const uint8_t* data, std::size_t size, const std::function<void(const GdosRecord&)>& sink);
  // The name of a component address from the hosts' TiMS announcements, or "".
  [[nodiscard]] std::string announced_name(uint32_t address) const;
  [[nodiscard]] GdosSubscriberCounters counters() const noexcept;
  // Warnings to show the user (malformed batches, losses); cleared by the call.
  [[nodiscard]] std::string take_warnings();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rack::tims
