// Access control for TiMS mailboxes (RACK's planned domain and type enforcement):
// which sources may send which message types to which components, at what priority,
// and how fast.
//
// A rule names destinations (`to`: address masks, usually one component's mailboxes)
// and sources (`from`: address masks, and/or "local" = sent inside this process,
// "network" = arrived over TiMS/LCM; none given: any source). The FIRST rule whose
// `to` and `from` match a message decides, in this order:
//   1. type: a request (type > 0) must be in the rule's types (no list: any type);
//      replies and notifications (type <= 0) pass this step unless the rule lists
//      reply types itself (then only those);
//   2. priority: at most max_priority;
//   3. rate and bandwidth: a token bucket PER SOURCE ADDRESS and rule (messages/s
//      with a burst, bytes/s with a burst), so that a flood from one source uses up
//      only its own bucket.
// No rule matches: the default policy decides. kOpen lets everything through (the
// behaviour without an `access:` section); kClosed refuses requests and lets replies
// and notifications through (they answer what the component asked for; a rule can
// still restrict them).
//
// Buckets: a fixed table of per-source entries (lock-free, bounded probing, entries
// whose bucket has refilled are reused). When the table is full for a source (many
// sources at once), that source shares its rule's overflow bucket: newcomers in a
// crowd compete among themselves, never with the sources that already have an entry.
//
// Real-time contract: check() is RT-safe and lock-free (no allocation, no system call
// but the vDSO clock, bounded loops: rules x masks, kProbe probes). The constructor,
// describe functions and report() are not (set-up and a non-RT reporting thread).
// Thread-safety: check() from any number of threads at once; counters from any thread.
#pragma once

#include <array>
#include <atomic>
#include <bitset>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rack/tims/message.h"

namespace rack::tims {

// value/mask over the 32 address bits: matches when (address & mask) == value.
struct AddressMask {
  uint32_t value = 0;
  uint32_t mask = 0;
  [[nodiscard]] constexpr bool matches(Address a) const noexcept { return (a.raw() & mask) == value; }
};

// Where a message entered the router.
enum class MessageOrigin : uint8_t { kLocal, kNetwork };

enum class AccessVerdict : uint8_t {
  kAllowed,
  kDeniedType,       // the matching rule does not allow this type
  kDeniedPriority,   // above the rule's max_priority
  kDeniedRate,       // the source's message bucket is empty
  kDeniedBandwidth,  // the source's byte bucket is empty
  kDeniedDefault,    // no rule matched and the default policy is closed
};
[[nodiscard]] const char* describe(AccessVerdict v) noexcept;

enum class AccessDefault : uint8_t { kOpen, kClosed };

// One rule as configured (set-up form; the host file's `access: rules:`).
struct AccessRuleConfig {
  std::string name;               // for counters and logs ("rule 3" when empty)
  std::vector<AddressMask> to;    // at least one
  std::vector<AddressMask> from;  // empty with from_local/from_network false: any source
  bool from_local = false;
  bool from_network = false;
  bool only_local = false;         // and only messages sent inside this process (rackd's own)
  bool any_type = true;            // false: only `types` (requests, and replies when listed)
  std::bitset<256> types;          // index: type + 128
  bool restricts_replies = false;  // `types` lists a type <= 0
  int max_priority = 255;
  double rate = 0;         // messages per second per source; 0: no limit
  double burst = 0;        // messages (0: max(1, rate / 10))
  double bandwidth = 0;    // bytes per second per source; 0: no limit
  double burst_bytes = 0;  // bytes (0: max(64 KiB, bandwidth / 10))
};

struct AccessConfig {
  AccessDefault default_policy = AccessDefault::kOpen;
  std::vector<AccessRuleConfig> rules;
  uint32_t sources = 1024;  // per-source bucket entries (rounded up to a power of 2)
};

struct AccessRuleCounters {
  std::string name;
  uint64_t allowed = 0;
  uint64_t denied_type = 0;
  uint64_t denied_priority = 0;
  uint64_t denied_rate = 0;
  uint64_t denied_bandwidth = 0;
  [[nodiscard]] uint64_t denied() const noexcept {
    return denied_type + denied_priority + denied_rate + denied_bandwidth;
  }
};

struct AccessDecision {
  AccessVerdict verdict = AccessVerdict::kAllowed;
  int rule = -1;  // index of the deciding rule; -1: the default policy
  // A refused request is answered ERROR, at most kRepliesPerSecond times per rule (a
  // flood of refused requests must not become a flood of replies on the uplink);
  // false: refused silently (still counted).
  bool answer = false;
  [[nodiscard]] bool allowed() const noexcept { return verdict == AccessVerdict::kAllowed; }
};

class AccessControl {
 public:
  static constexpr std::size_t kMaxRules = 64;
  static constexpr std::size_t kMaxMasks = 16;  // per `to` and per `from`
  static constexpr std::size_t kProbe = 8;      // bucket table probes per look-up
  static constexpr std::size_t kNameLen = 32;
  static constexpr int64_t kRepliesPerSecond = 50;  // ERROR answers per rule (burst as many)

  // Resolves the configuration into fixed tables. Throws std::invalid_argument naming
  // the rule when it exceeds a limit. Not RT-safe.
  explicit AccessControl(const AccessConfig& config);
  AccessControl(const AccessControl&) = delete;
  AccessControl& operator=(const AccessControl&) = delete;

  // Decides on one message (header in host byte order); counts the decision and, on a
  // denial, remembers it for report(). `now_ns`: CLOCK_MONOTONIC. RT-safe, lock-free.
  [[nodiscard]] AccessDecision check(const MessageHeader& h, MessageOrigin origin, int64_t now_ns) noexcept;
  // The same with the clock read here. RT-safe.
  [[nodiscard]] AccessDecision check(const MessageHeader& h, MessageOrigin origin) noexcept;

  // The ERROR reply text of a denial: "access denied by rule 'NAME': REASON". RT-safe.
  void denial_text(const AccessDecision& d, char* out, std::size_t size) const noexcept;

  [[nodiscard]] AccessDefault default_policy() const noexcept { return default_; }
  [[nodiscard]] std::size_t rule_count() const noexcept { return rule_count_; }
  [[nodiscard]] std::vector<AccessRuleCounters> counters() const;  // not RT-safe
  [[nodiscard]] uint64_t denied_default() const noexcept { return denied_default_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t overflow_uses() const noexcept { return overflow_uses_.load(std::memory_order_relaxed); }
  // Total denials (every rule and the default policy). RT-safe.
  [[nodiscard]] uint64_t denied_total() const noexcept;

  // One line per rule (and the default policy) with denials since the last call:
  // count, reason and the last message refused. For the GDOS log at a bounded rate:
  // the caller decides how often. Not RT-safe; one reporting thread.
  [[nodiscard]] std::vector<std::string> report();

  // One line per rule with its counters, for status displays. Not RT-safe.
  [[nodiscard]] std::string status_text() const;

 private:
  struct Rule {
    std::array<char, kNameLen> name{};
    std::array<AddressMask, kMaxMasks> to{};
    std::size_t to_count = 0;
    std::array<AddressMask, kMaxMasks> from{};
    std::size_t from_count = 0;
    bool any_source = true;
    bool from_local = false;
    bool from_network = false;
    bool only_local = false;
    bool any_type = true;
    bool restricts_replies = false;
    std::bitset<256> types;
    int max_priority = 255;
    int64_t msg_interval_ns = 0;   // 0: no message limit
    int64_t msg_tolerance_ns = 0;  // burst * interval
    double byte_ns = 0;            // ns per byte; 0: no bandwidth limit
    int64_t byte_tolerance_ns = 0;
    // Counters (relaxed: independent statistics).
    std::atomic<uint64_t> allowed{0}, denied_type{0}, denied_priority{0}, denied_rate{0}, denied_bandwidth{0};
    // The last denial, for the report (relaxed; a report may mix two denials' fields).
    std::atomic<uint64_t> last_src_dst{0};
    std::atomic<uint32_t> last_type_prio_verdict{0};
    uint64_t reported = 0;  // denials already reported (reporting thread only)
    // Shared bucket of sources without an entry of their own.
    std::atomic<int64_t> overflow_msg_tat{0}, overflow_byte_tat{0};
    std::atomic<int64_t> reply_tat{0};  // ERROR answers of this rule (GCRA)
  };
  // A source's buckets in one rule: GCRA ("virtual scheduling"): tat is the time at
  // which the bucket is full again; a message is let through when tat stays within
  // the tolerance (the burst) of now. One atomic per bucket: lock-free.
  struct SourceEntry {
    std::atomic<uint64_t> key{0};  // (rule + 1) << 32 | source; 0: empty
    std::atomic<int64_t> msg_tat{0};
    std::atomic<int64_t> byte_tat{0};
  };

  [[nodiscard]] bool matches(const Rule& r, const MessageHeader& h, MessageOrigin origin) const noexcept;
  [[nodiscard]] AccessVerdict limit(std::size_t rule_index, Rule& r, const MessageHeader& h, int64_t now) noexcept;
  void remember(Rule& r, const MessageHeader& h, AccessVerdict v) noexcept;

  AccessDefault default_ = AccessDefault::kOpen;
  std::array<Rule, kMaxRules> rules_{};
  std::size_t rule_count_ = 0;
  std::unique_ptr<SourceEntry[]> sources_;
  std::size_t source_mask_ = 0;
  std::atomic<uint64_t> denied_default_{0}, overflow_uses_{0};
  std::atomic<uint64_t> default_last_src_dst_{0};
  std::atomic<uint32_t> default_last_type_{0};
  std::atomic<int64_t> default_reply_tat_{0};
  uint64_t default_reported_ = 0;
};

// Parses a message type name (RACK's generic ones: on, off, get_status, get_data,
// get_cont_data, stop_cont_data, get_next_data, get_param, set_param, get_stats,
// get_latency, get_class, and
// the replies ok, error, data, ...) or a number -128..127. false: unknown. Not RT-safe.
[[nodiscard]] bool parse_message_type(const std::string& text, int8_t& out) noexcept;

// Parses an address pattern: `Class(sys/inst)`, `Class(sys/*)`, `*(sys/*)`,
// `Class(*/*)`, `*` (everything), optionally with `#mbx`; or a value/mask pair
// `0x10000000/0xff000000`. Without `#mbx` the pattern covers every local mailbox.
// nullopt when malformed. Not RT-safe.
[[nodiscard]] std::optional<AddressMask> parse_address_mask(const std::string& text);

}  // namespace rack::tims
