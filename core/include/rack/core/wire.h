// Bodies of RACK's generic messages (DESIGN.md message numbers). Every struct is a
// TiMS payload (rack/tims/payload.h): fixed layout, field table for byte order.
//
// Real-time contract: plain data; everything here is RT-safe.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

#include "rack/tims/payload.h"

namespace rack::wire {

// GET_DATA request: time 0 = newest, else the sample nearest that host time.
struct GetDataRequest {
  int64_t time_ns = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(GetDataRequest, time_ns)}; }
};

// GET_CONT_DATA request: send every n-th sample to `mailbox`, n from the period.
struct ContDataRequest {
  int64_t period_ns = 0;  // 0: every sample
  uint32_t mailbox = 0;   // where the samples go
  uint32_t reserved = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ContDataRequest, period_ns), RACK_FIELD(ContDataRequest, mailbox)};
  }
};

// CONT_DATA reply: the period the listener will really get, and its lease: the
// subscription is dropped unless the same mailbox sends GET_CONT_DATA again within
// lease_ns (a renewal: it keeps the slot and its place in the reduction). 0: no lease.
struct ContDataReply {
  int64_t period_ns = 0;
  int64_t lease_ns = 0;
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ContDataReply, period_ns), RACK_FIELD(ContDataReply, lease_ns)};
  }
};

// STOP_CONT_DATA request.
struct StopContDataRequest {
  uint32_t mailbox = 0;
  uint32_t reserved = 0;
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(StopContDataRequest, mailbox)}; }
};

// Every DATA message body starts with this, followed by the class's sample.
struct SampleHeader {
  int64_t time_ns = 0;    // recording time (host clock)
  uint64_t sequence = 0;  // per producer, counts every sample written
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(SampleHeader, time_ns), RACK_FIELD(SampleHeader, sequence)};
  }
};

// ERROR reply body (optional): a NUL-terminated reason.
struct ErrorText {
  char text[120] = {};
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(ErrorText, text)}; }
};

enum class ParamKind : uint8_t { kInt = 0, kFloat = 1, kBool = 2, kString = 3 };
inline constexpr std::size_t kParamNameLen = 32;
inline constexpr std::size_t kParamStringLen = 128;

// GET_PARAM request body (empty body: every parameter), SET_PARAM/PARAM record.
struct ParamName {
  char name[kParamNameLen] = {};
  static constexpr auto fields() noexcept { return std::array{RACK_FIELD(ParamName, name)}; }
};

struct ParamRecord {
  char name[kParamNameLen] = {};
  uint8_t kind = 0;   // ParamKind
  uint8_t flags = 0;  // bit 0: names a component (address reference)
  uint8_t reserved[6] = {};
  int64_t int_value = 0;     // kInt, kBool (0/1)
  double float_value = 0.0;  // kFloat
  char string_value[kParamStringLen] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ParamRecord, name),        RACK_FIELD(ParamRecord, kind),
                      RACK_FIELD(ParamRecord, flags),       RACK_FIELD(ParamRecord, int_value),
                      RACK_FIELD(ParamRecord, float_value), RACK_FIELD(ParamRecord, string_value)};
  }
};

// Timing of one task (GET_STATS).
struct TaskStats {
  uint64_t cycles = 0;
  uint64_t overruns = 0;
  uint64_t samples = 0;
  int64_t latency_min_ns = 0;
  int64_t latency_max_ns = 0;
  int64_t latency_p50_ns = 0;
  int64_t latency_p99_ns = 0;
  int64_t latency_p999_ns = 0;
  int64_t latency_mean_ns = 0;
};

// STATS reply body.
struct StatsReply {
  uint8_t state = 0;            // ComponentState
  uint8_t data_task = 0;        // 0 none, 1 periodic, 2 triggered
  uint8_t faults_measured = 0;  // bit 0: command task's page faults measured, bit 1: data task's
  uint8_t reserved[5] = {};
  int64_t period_ns = 0;
  TaskStats data;
  uint64_t commands = 0;        // requests handled by the command task
  uint64_t malformed = 0;       // requests rejected as malformed (answered ERROR)
  uint64_t errors = 0;          // transitions into ERROR
  uint64_t listeners = 0;       // current getContData listeners
  uint64_t published = 0;       // samples written
  uint64_t listener_drops = 0;  // samples a listener's mailbox refused
  uint64_t command_drops = 0;   // command mailbox drops + refusals
  uint64_t stale_replies = 0;
  // Page faults of each task since the end of its start-up (rack/rt/page_faults.h):
  // 0 is the target for an RT task; counted by a non-RT thread once a second.
  uint64_t command_minor_faults = 0;
  uint64_t command_major_faults = 0;
  uint64_t data_minor_faults = 0;
  uint64_t data_major_faults = 0;
  uint64_t access_denied = 0;  // messages to it that access control refused
  // Its data (input) mailbox (rack/tims/trusted_sources.h), refused before queuing:
  uint64_t input_forged = 0;       // replies/notifications not from a subscribed producer
  uint64_t input_requests = 0;     // requests sent into it (answered NOT_AVAILABLE, rate-limited)
                                   // or into its reply mailboxes #1, #2 (dropped)
  uint64_t input_late = 0;         // messages of a producer unsubscribed just before (in flight)
  uint64_t listeners_expired = 0;  // listeners dropped because their lease ran out
  // Execution time of the data task's cycles (how long loop() ran; periodic and
  // triggered tasks alike), from a fixed log-linear histogram (rack/rt/exec_time_stats.h,
  // within 3 %); exec_samples 0: none measured (no data task, or loop() never ran).
  uint64_t exec_samples = 0;
  int64_t exec_p50_ns = 0;
  int64_t exec_p99_ns = 0;
  int64_t exec_max_ns = 0;
  // Why the component is in ERROR (Component::set_error_reason, or the framework's:
  // a producer that left ENABLED, a failed cascading ON with the dependency's reason,
  // init()'s error); "" when it is not in ERROR.
  char error_reason[96] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(StatsReply, state),
                      RACK_FIELD(StatsReply, data_task),
                      RACK_FIELD(StatsReply, faults_measured),
                      RACK_FIELD(StatsReply, period_ns),
                      RACK_FIELD(StatsReply, data.cycles),
                      RACK_FIELD(StatsReply, data.overruns),
                      RACK_FIELD(StatsReply, data.samples),
                      RACK_FIELD(StatsReply, data.latency_min_ns),
                      RACK_FIELD(StatsReply, data.latency_max_ns),
                      RACK_FIELD(StatsReply, data.latency_p50_ns),
                      RACK_FIELD(StatsReply, data.latency_p99_ns),
                      RACK_FIELD(StatsReply, data.latency_p999_ns),
                      RACK_FIELD(StatsReply, data.latency_mean_ns),
                      RACK_FIELD(StatsReply, commands),
                      RACK_FIELD(StatsReply, malformed),
                      RACK_FIELD(StatsReply, errors),
                      RACK_FIELD(StatsReply, listeners),
                      RACK_FIELD(StatsReply, published),
                      RACK_FIELD(StatsReply, listener_drops),
                      RACK_FIELD(StatsReply, command_drops),
                      RACK_FIELD(StatsReply, stale_replies),
                      RACK_FIELD(StatsReply, command_minor_faults),
                      RACK_FIELD(StatsReply, command_major_faults),
                      RACK_FIELD(StatsReply, data_minor_faults),
                      RACK_FIELD(StatsReply, data_major_faults),
                      RACK_FIELD(StatsReply, access_denied),
                      RACK_FIELD(StatsReply, input_forged),
                      RACK_FIELD(StatsReply, input_requests),
                      RACK_FIELD(StatsReply, input_late),
                      RACK_FIELD(StatsReply, listeners_expired),
                      RACK_FIELD(StatsReply, exec_samples),
                      RACK_FIELD(StatsReply, exec_p50_ns),
                      RACK_FIELD(StatsReply, exec_p99_ns),
                      RACK_FIELD(StatsReply, exec_max_ns),
                      RACK_FIELD(StatsReply, error_reason)};
  }
};

// GET_LATENCY's reply (LATENCY): the data task's wake-up latency histogram, coarse
// enough for one message and a terminal, fine enough for a 20 us jitter and a 5 ms
// overrun alike. The component adds its 1-us histogram (rack/rt/latency_stats.h) up
// into these buckets in the command task (no allocation).
//
// Bucket j holds the wake-up latencies in [lower_ns[j], lower_ns[j+1]); the last one
// is open (>= 10 ms). Edges: 1-us steps up to 8 us (where a PREEMPT_RT host's jitter
// lives), then 10 a decade (1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8 x 10^n us) up to 10 ms.
// Every edge is a whole microsecond, so the sums are exact.
//
// The reply carries its edges (lower_ns) although they are this fixed table: a client
// (rackctl, rack-gui, a tool in another language) draws what the component measured
// without a copy of the table, and a later version may change the edges without
// breaking old clients. 320 bytes more per reply, which is asked for once a second
// at most. A different bucket count changes the size, which read_payload refuses.
inline constexpr std::size_t kLatencyBuckets = 40;
inline constexpr std::array<int64_t, kLatencyBuckets> kLatencyLowerNs = {
    0,         1'000,     2'000,     3'000,     4'000,     5'000,     6'000,     7'000,     8'000,     10'000,
    12'000,    15'000,    20'000,    25'000,    30'000,    40'000,    50'000,    60'000,    80'000,    100'000,
    120'000,   150'000,   200'000,   250'000,   300'000,   400'000,   500'000,   600'000,   800'000,   1'000'000,
    1'200'000, 1'500'000, 2'000'000, 2'500'000, 3'000'000, 4'000'000, 5'000'000, 6'000'000, 8'000'000, 10'000'000};

struct LatencyHistogram {
  uint8_t data_task = 0;  // as StatsReply: 0 none (all counts 0), 1 periodic, 2 triggered
  uint8_t reserved[3] = {};
  uint32_t bucket_count = 0;  // buckets in use (kLatencyBuckets); a client reads only these
  int64_t period_ns = 0;
  uint64_t cycles = 0;
  uint64_t overruns = 0;  // periods missed (skipped, never caught up)
  uint64_t samples = 0;   // the sum of counts (one snapshot of the histogram)
  int64_t min_ns = 0;
  int64_t max_ns = 0;
  int64_t mean_ns = 0;
  int64_t p50_ns = 0;  // percentiles from the 1-us histogram (as GET_STATS)
  int64_t p99_ns = 0;
  int64_t p999_ns = 0;
  int64_t lower_ns[kLatencyBuckets] = {};
  uint64_t counts[kLatencyBuckets] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(LatencyHistogram, data_task), RACK_FIELD(LatencyHistogram, bucket_count),
                      RACK_FIELD(LatencyHistogram, period_ns), RACK_FIELD(LatencyHistogram, cycles),
                      RACK_FIELD(LatencyHistogram, overruns),  RACK_FIELD(LatencyHistogram, samples),
                      RACK_FIELD(LatencyHistogram, min_ns),    RACK_FIELD(LatencyHistogram, max_ns),
                      RACK_FIELD(LatencyHistogram, mean_ns),   RACK_FIELD(LatencyHistogram, p50_ns),
                      RACK_FIELD(LatencyHistogram, p99_ns),    RACK_FIELD(LatencyHistogram, p999_ns),
                      RACK_FIELD(LatencyHistogram, lower_ns),  RACK_FIELD(LatencyHistogram, counts)};
  }
};

// What is wrong with a LATENCY reply a client received, or nullptr when it is usable:
// bucket_count 1..kLatencyBuckets, lower_ns[0] == 0 and increasing, counts summing
// to samples. RT-safe.
[[nodiscard]] inline const char* check_latency_histogram(const LatencyHistogram& h) noexcept {
  if (h.bucket_count == 0 || h.bucket_count > kLatencyBuckets) return "bucket_count is not 1..40";
  if (h.lower_ns[0] != 0) return "the first bucket does not start at 0";
  uint64_t sum = 0;
  for (std::size_t j = 0; j < h.bucket_count; ++j) {
    if (j > 0 && h.lower_ns[j] <= h.lower_ns[j - 1]) return "bucket edges do not increase";
    if (h.counts[j] > UINT64_MAX - sum) return "bucket counts overflow";
    sum += h.counts[j];
  }
  if (sum != h.samples) return "bucket counts do not add up to samples";
  return nullptr;
}

// GET_LISTENERS' reply (LISTENERS): who subscribes to a data component (GET_CONT_DATA)
// now, so that a tool draws the data flows that really run (rackctl graph --live)
// beside the ones the host files declare. Entry i of the arrays (i < count) is one
// continuous listener whose lease has not run out: the mailbox its samples go to (a
// component's input mailbox, a tool's data mailbox), the reduction factor (every
// factor-th sample) and the period it gets (factor x the producer's period; 0 for a
// triggered producer that has not published twice yet), and how long ago it renewed.
// One-shot requests (GET_NEXT_DATA) are not listed. `total` counts every such
// listener; more than kMaxListenerRecords are cut (count < total). A component
// without a data task answers count 0, data_task 0.
inline constexpr std::size_t kMaxListenerRecords = 32;
struct ListenersReply {
  uint8_t data_task = 0;  // as StatsReply: 0 none, 1 periodic, 2 triggered
  uint8_t reserved[3] = {};
  uint32_t count = 0;                          // entries in use (<= kMaxListenerRecords)
  uint32_t total = 0;                          // listeners at the time of the reply (>= count)
  uint32_t reserved2 = 0;                      // 0
  int64_t period_ns = 0;                       // the producer's period (periodic), else its last interval
  uint32_t mailbox[kMaxListenerRecords] = {};  // raw TiMS address of the listener's mailbox
  uint32_t factor[kMaxListenerRecords] = {};   // >= 1
  int64_t listener_period_ns[kMaxListenerRecords] = {};
  int64_t renewed_ago_ns[kMaxListenerRecords] = {};  // since its last GET_CONT_DATA (>= 0)
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(ListenersReply, data_task),
                      RACK_FIELD(ListenersReply, count),
                      RACK_FIELD(ListenersReply, total),
                      RACK_FIELD(ListenersReply, period_ns),
                      RACK_FIELD(ListenersReply, mailbox),
                      RACK_FIELD(ListenersReply, factor),
                      RACK_FIELD(ListenersReply, listener_period_ns),
                      RACK_FIELD(ListenersReply, renewed_ago_ns)};
  }
};
static_assert(sizeof(ListenersReply) == 792, "LISTENERS: a fixed layout on the wire");

// What is wrong with a LISTENERS reply a client received, or nullptr when it is
// usable: data_task 0..2, count <= kMaxListenerRecords and <= total, no listeners
// without a data task, and each entry in use: a factor >= 1, periods and renewal
// ages >= 0, a mailbox that is not 0. RT-safe.
[[nodiscard]] inline const char* check_listeners_reply(const ListenersReply& r) noexcept {
  if (r.data_task > 2) return "data_task is not 0..2";
  if (r.count > kMaxListenerRecords) return "count is above 32";
  if (r.count > r.total) return "count is above total";
  if (r.data_task == 0 && r.total != 0) return "listeners without a data task";
  if (r.period_ns < 0) return "period_ns is negative";
  for (std::size_t i = 0; i < r.count; ++i) {
    if (r.mailbox[i] == 0) return "a listener's mailbox is 0";
    if (r.factor[i] == 0) return "a listener's factor is 0";
    if (r.listener_period_ns[i] < 0) return "a listener's period is negative";
    if (r.renewed_ago_ns[i] < 0) return "a listener's renewal age is negative";
  }
  return nullptr;
}

// Reads a payload from a body: exact size required, byte order converted when the
// sender's differs. false: wrong size. RT-safe.
template <tims::Payload T>
[[nodiscard]] bool read_payload(std::span<const std::byte> body, bool native, T& out) noexcept {
  if (body.size() != sizeof(T)) return false;
  std::memcpy(&out, body.data(), sizeof(T));
  if (!native) tims::swap_fields(tims::fields_of<T>, reinterpret_cast<std::byte*>(&out), sizeof(T));
  return true;
}

// Decodes a LISTENERS body: nullptr with `out` filled, else what is wrong (the size,
// or check_listeners_reply's answer). The fuzz harness' entry. RT-safe.
[[nodiscard]] inline const char* decode_listeners(std::span<const std::byte> body, bool native,
                                                  ListenersReply& out) noexcept {
  if (!read_payload(body, native, out)) return "the body is not the size of a LISTENERS reply (792 bytes)";
  return check_listeners_reply(out);
}

// Copies a NUL-terminated string into a fixed char array (always terminated). RT-safe.
template <std::size_t N>
void copy_text(char (&dst)[N], const char* src) noexcept {
  std::size_t i = 0;
  for (; src != nullptr && src[i] != '\0' && i + 1 < N; ++i) dst[i] = src[i];
  dst[i] = '\0';
}

// Appends to a NUL-terminated fixed char array (cuts at the end). RT-safe.
template <std::size_t N>
void append_text(char (&dst)[N], const char* src) noexcept {
  std::size_t i = 0;
  while (i < N && dst[i] != '\0') ++i;
  for (std::size_t j = 0; src != nullptr && src[j] != '\0' && i + 1 < N; ++i, ++j) dst[i] = src[j];
  if (i < N) dst[i] = '\0';
}

}  // namespace rack::wire
