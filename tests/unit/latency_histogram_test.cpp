// GET_LATENCY: the data task's 1-us wake-up latency histogram added up into the
// reply's buckets (rt::LatencyStats::compress, wire::kLatencyLowerNs), the reply in
// both byte orders, and the command through a real in-process executor (a periodic
// generator; a malformed request). A periodic task's phase_ms puts its deadlines on the
// clock's grid.
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstddef>
#include <cstring>
#include <numeric>
#include <vector>

#include "rack/components/class_ids.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/demo.h"
#include "rack/rt/clock.h"
#include "rack/rt/latency_stats.h"
#include "test_support.h"

namespace rack {
namespace {

using test::HostUnderTest;
using test::Watchdog;
using tims::Address;
namespace msg = tims::msg;

// The reply bucket that holds `ns`, found from the table independently of compress().
std::size_t bucket_of(int64_t ns) {
  std::size_t j = 0;
  while (j + 1 < wire::kLatencyBuckets && wire::kLatencyLowerNs[j + 1] <= ns) ++j;
  return j;
}

TEST(LatencyHistogramTest, TableStartsAtZeroIncreasesAndEndsOpenAtTenMs) {
  EXPECT_EQ(wire::kLatencyLowerNs.front(), 0);
  for (std::size_t j = 1; j < wire::kLatencyBuckets; ++j) {
    EXPECT_GT(wire::kLatencyLowerNs[j], wire::kLatencyLowerNs[j - 1]) << j;
    EXPECT_EQ(wire::kLatencyLowerNs[j] % rt::LatencyStats::kBucketNs, 0) << "whole microseconds: exact sums";
  }
  EXPECT_EQ(wire::kLatencyLowerNs.back(), 10'000'000);
}

TEST(LatencyHistogramTest, KnownLatenciesLandInTheirBuckets) {
  auto stats = std::make_unique<rt::LatencyStats>();
  // ns -> the expected lower edge of its reply bucket.
  const std::vector<std::pair<int64_t, int64_t>> cases = {
      {-5, 0},  // a clock oddity counts as 0
      {0, 0},
      {999, 0},
      {1'000, 1'000},
      {7'999, 7'000},
      {8'000, 8'000},
      {9'999, 8'000},  // 8..10 us
      {10'000, 10'000},
      {20'500, 20'000},  // a 20 us jitter
      {119'999, 100'000},
      {120'000, 120'000},
      {5'000'000, 5'000'000},    // a 5 ms overrun
      {9'999'999, 8'000'000},    // just below the open bucket
      {10'000'000, 10'000'000},  // the open bucket
      {55'000'000, 10'000'000},  // far beyond: still the open bucket
  };
  std::array<uint64_t, wire::kLatencyBuckets> want{};
  for (const auto& [ns, lower] : cases) {
    stats->record_latency(ns);
    const std::size_t j = bucket_of(lower);
    ASSERT_EQ(wire::kLatencyLowerNs[j], lower) << ns;
    ++want[j];
  }
  // Many of one value: counts add, not just mark.
  for (int i = 0; i < 1000; ++i) stats->record_latency(4'200);
  want[bucket_of(4'000)] += 1000;

  std::array<uint64_t, wire::kLatencyBuckets> counts{};
  counts.fill(777);  // compress sets, never adds to, what was there
  const uint64_t total = stats->compress(wire::kLatencyLowerNs, counts);
  EXPECT_EQ(total, cases.size() + 1000);
  EXPECT_EQ(total, stats->summary().samples);
  for (std::size_t j = 0; j < wire::kLatencyBuckets; ++j) {
    EXPECT_EQ(counts[j], want[j]) << "bucket " << j << " from " << wire::kLatencyLowerNs[j] << " ns";
  }
}

TEST(LatencyHistogramTest, CompressRefusesMismatchedTables) {
  rt::LatencyStats stats;
  stats.record_latency(3'000);
  std::array<uint64_t, 3> counts{5, 5, 5};
  const std::array<int64_t, 2> lower{0, 1'000};
  EXPECT_EQ(stats.compress(lower, counts), 0u);
  EXPECT_EQ(counts, (std::array<uint64_t, 3>{0, 0, 0}));
  // A table of one bucket: everything in it.
  std::array<uint64_t, 1> one{};
  EXPECT_EQ(stats.compress(std::array<int64_t, 1>{0}, one), 1u);
  EXPECT_EQ(one[0], 1u);
}

// A reply with a value in every field, so a field missing from the table shows.
wire::LatencyHistogram sample_reply() {
  wire::LatencyHistogram h;
  h.data_task = 1;
  h.bucket_count = static_cast<uint32_t>(wire::kLatencyBuckets);
  h.period_ns = 10'000'000;
  h.cycles = 123'456;
  h.overruns = 3;
  h.min_ns = 1'234;
  h.max_ns = 5'432'100;
  h.mean_ns = 4'321;
  h.p50_ns = 4'000;
  h.p99_ns = 21'000;
  h.p999_ns = 800'000;
  h.samples = 0;
  for (std::size_t j = 0; j < wire::kLatencyBuckets; ++j) {
    h.lower_ns[j] = wire::kLatencyLowerNs[j];
    h.counts[j] = 0x0100000000000000ull * (j % 3) + j * 1'000 + 7;
    h.samples += h.counts[j];
  }
  return h;
}

// Writes the reply as a peer of the given byte order sends it, field by field by hand
// (independent of the field table under test).
template <typename T>
void put(std::byte* at, T v, bool little) {
  auto u = std::bit_cast<std::conditional_t<sizeof(T) == 8, uint64_t, uint32_t>>(v);
  for (std::size_t i = 0; i < sizeof u; ++i) {
    const std::size_t shift = 8 * (little ? i : sizeof u - 1 - i);
    at[i] = static_cast<std::byte>((u >> shift) & 0xff);
  }
}
std::vector<std::byte> encode(const wire::LatencyHistogram& h, bool little) {
  using H = wire::LatencyHistogram;
  std::vector<std::byte> b(sizeof(H));
  b[offsetof(H, data_task)] = static_cast<std::byte>(h.data_task);
  put(b.data() + offsetof(H, bucket_count), h.bucket_count, little);
  put(b.data() + offsetof(H, period_ns), h.period_ns, little);
  put(b.data() + offsetof(H, cycles), h.cycles, little);
  put(b.data() + offsetof(H, overruns), h.overruns, little);
  put(b.data() + offsetof(H, samples), h.samples, little);
  put(b.data() + offsetof(H, min_ns), h.min_ns, little);
  put(b.data() + offsetof(H, max_ns), h.max_ns, little);
  put(b.data() + offsetof(H, mean_ns), h.mean_ns, little);
  put(b.data() + offsetof(H, p50_ns), h.p50_ns, little);
  put(b.data() + offsetof(H, p99_ns), h.p99_ns, little);
  put(b.data() + offsetof(H, p999_ns), h.p999_ns, little);
  for (std::size_t j = 0; j < wire::kLatencyBuckets; ++j) {
    put(b.data() + offsetof(H, lower_ns) + 8 * j, h.lower_ns[j], little);
    put(b.data() + offsetof(H, counts) + 8 * j, h.counts[j], little);
  }
  return b;
}

TEST(LatencyHistogramTest, ReplyReadsBackInBothByteOrders) {
  const wire::LatencyHistogram want = sample_reply();
  ASSERT_EQ(wire::check_latency_histogram(want), nullptr);
  for (const bool little : {true, false}) {
    SCOPED_TRACE(little ? "little-endian peer" : "big-endian peer");
    const std::vector<std::byte> body = encode(want, little);
    tims::MessageHeader h = tims::make_header(Address::make(0, tims::classes::kTool, 1),
                                              Address::make(0, class_ids::kGenerator, 1), msg::kLatency, 0, 0,
                                              body.size());
    h.flags = static_cast<uint8_t>(tims::kFlagHeaderLittleEndian | (little ? tims::kFlagBodyLittleEndian : 0));
    wire::LatencyHistogram got;
    ASSERT_TRUE(wire::read_payload(body, tims::body_is_native(h), got));
    EXPECT_EQ(std::memcmp(&got, &want, sizeof got), 0);
    EXPECT_EQ(wire::check_latency_histogram(got), nullptr);
    // A body of another size (another bucket count) is refused, not misread.
    EXPECT_FALSE(wire::read_payload(std::span<const std::byte>(body).first(body.size() - 8), true, got));
  }
}

TEST(LatencyHistogramTest, CheckNamesWhatIsWrongWithAReply) {
  wire::LatencyHistogram h = sample_reply();
  h.bucket_count = 0;
  EXPECT_STREQ(wire::check_latency_histogram(h), "bucket_count is not 1..40");
  h = sample_reply();
  h.bucket_count = 41;
  EXPECT_STREQ(wire::check_latency_histogram(h), "bucket_count is not 1..40");
  h = sample_reply();
  h.lower_ns[5] = h.lower_ns[4];
  EXPECT_STREQ(wire::check_latency_histogram(h), "bucket edges do not increase");
  h = sample_reply();
  h.lower_ns[0] = 5;
  EXPECT_STREQ(wire::check_latency_histogram(h), "the first bucket does not start at 0");
  h = sample_reply();
  h.samples += 1;
  EXPECT_STREQ(wire::check_latency_histogram(h), "bucket counts do not add up to samples");
  h = sample_reply();
  h.counts[0] = UINT64_MAX;
  EXPECT_STREQ(wire::check_latency_histogram(h), "bucket counts overflow");
}

// Through an in-process executor: Generator(0/1), periodic every 2 ms.
class LatencyCommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    data_task: {period_ms: 2, ring: 16}
)");
    gen_ = host_->address_of("gen");
  }
  void TearDown() override {
    if (host_ && HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
  }
  wire::LatencyHistogram latency() {
    const auto r = host_->call(gen_, msg::kGetLatency);
    wire::LatencyHistogram h;
    EXPECT_EQ(r.status, tims::CallStatus::kOk);
    EXPECT_EQ(r.type, msg::kLatency) << r.error_text();
    const std::span<const std::byte> body(reinterpret_cast<const std::byte*>(r.body.data()), r.body.size());
    EXPECT_TRUE(wire::read_payload(body, true, h)) << r.body.size() << " bytes";
    return h;
  }
  std::unique_ptr<HostUnderTest> host_;
  Address gen_;
};

TEST_F(LatencyCommandTest, PeriodicGeneratorReportsItsSamplesInTheFixedBuckets) {
  Watchdog dog;
  // Before ON: the table. A periodic data task wakes up (and counts its wake-ups) from
  // the executor's start, so a start slower than the 2 ms period may already show a
  // few samples: only their consistency is asserted here.
  wire::LatencyHistogram h = latency();
  EXPECT_EQ(h.data_task, 1);
  EXPECT_EQ(h.period_ns, 2'000'000);
  EXPECT_EQ(h.bucket_count, wire::kLatencyBuckets);
  EXPECT_EQ(wire::check_latency_histogram(h), nullptr);
  EXPECT_EQ(std::memcmp(h.lower_ns, wire::kLatencyLowerNs.data(), sizeof h.lower_ns), 0);

  ASSERT_EQ(host_->call(gen_, msg::kOn).type, msg::kOk);
  ASSERT_TRUE(test::eventually([&] { return latency().samples >= 20; }));
  ASSERT_EQ(host_->call(gen_, msg::kOff).type, msg::kOk);
  // A periodic data task keeps waking up (and counting cycles and wake-ups) while
  // DISABLED: GET_STATS and GET_LATENCY agree exactly when no cycle falls between
  // them, so read GET_LATENCY on both sides of GET_STATS until the two are the same
  // (a 2 ms period left too little time under ThreadSanitizer for a single try).
  wire::StatsReply s;
  ASSERT_TRUE(test::eventually([&] {
    h = latency();
    s = host_->stats(gen_);
    const wire::LatencyHistogram after = latency();
    return after.samples == h.samples && after.cycles == h.cycles && after.overruns == h.overruns &&
           after.min_ns == h.min_ns && after.max_ns == h.max_ns;
  }));
  EXPECT_EQ(wire::check_latency_histogram(h), nullptr);
  EXPECT_EQ(h.samples, s.data.samples);
  EXPECT_EQ(h.cycles, s.data.cycles);
  EXPECT_EQ(h.overruns, s.data.overruns);
  EXPECT_EQ(h.min_ns, s.data.latency_min_ns);
  EXPECT_EQ(h.max_ns, s.data.latency_max_ns);
  EXPECT_EQ(h.p99_ns, s.data.latency_p99_ns);
  // The minimum and the maximum lie in the first and the last non-empty bucket.
  std::size_t first = wire::kLatencyBuckets, last = 0;
  for (std::size_t j = 0; j < wire::kLatencyBuckets; ++j) {
    if (h.counts[j] == 0) continue;
    first = std::min(first, j);
    last = j;
  }
  ASSERT_LT(first, wire::kLatencyBuckets);
  EXPECT_EQ(first, bucket_of(h.min_ns));
  EXPECT_EQ(last, bucket_of(h.max_ns));
}

TEST_F(LatencyCommandTest, RequestWithABodyIsAnsweredErrorAndCounted) {
  Watchdog dog;
  const uint64_t before = host_->stats(gen_).malformed;
  const uint64_t body8 = 0;
  const auto r = host_->call(gen_, msg::kGetLatency, &body8, sizeof body8);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_EQ(r.error_text(), "GET_LATENCY takes no body");
  EXPECT_EQ(host_->stats(gen_).malformed, before + 1);
  // The component still answers.
  EXPECT_EQ(latency().bucket_count, wire::kLatencyBuckets);
}

// A periodic component that keeps the CLOCK_MONOTONIC time of its first cycles.
class WakeRecorder final : public DataComponent<interfaces::GeneratorData> {
 public:
  static constexpr std::size_t kKept = 40;
  WakeRecorder() : DataComponent(DataTaskMode::kPeriodic) {}
  HookResult loop() override {  // RT: no allocation
    const int64_t now = rt::monotonic_ns();
    const std::size_t i = count_.load(std::memory_order_relaxed);
    if (i < kKept) {
      times_[i] = now;
      count_.store(i + 1, std::memory_order_release);
    }
    return HookResult::kOk;
  }
  [[nodiscard]] std::size_t count() const noexcept { return count_.load(std::memory_order_acquire); }
  [[nodiscard]] int64_t time(std::size_t i) const noexcept { return times_[i]; }

 private:
  std::array<int64_t, kKept> times_{};
  std::atomic<std::size_t> count_{0};
};

// data_task.phase_ms: the deadlines are whole multiples of the period on CLOCK_MONOTONIC
// plus the phase. Two tasks started together with phases 1 ms and 6 ms of a 10 ms
// period wake, cycle after cycle, in the first half after their own grid point; had the
// phase been ignored, both would wake at the same offset and one of them would be off.
TEST(PeriodicPhaseTest, DeadlinesFallOnTheClocksGridPlusThePhase) {
  Watchdog dog;
  HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: early
    class: WakeRecorder
    instance: 1
    autostart: true
    data_task: {period_ms: 10, phase_ms: 1}
  - name: late
    class: WakeRecorder
    instance: 2
    autostart: true
    data_task: {period_ms: 10, phase_ms: 6}
)",
                     test::one_class<WakeRecorder>("WakeRecorder", "test: keeps its wake-up times"));
  auto* early = dynamic_cast<WakeRecorder*>(host.executor().find("early"));
  auto* late = dynamic_cast<WakeRecorder*>(host.executor().find("late"));
  ASSERT_NE(early, nullptr);
  ASSERT_NE(late, nullptr);
  ASSERT_TRUE(test::eventually([&] { return early->count() >= 20 && late->count() >= 20; }));
  constexpr int64_t kPeriod = 10'000'000;
  for (const auto& [task, phase] : {std::pair{early, int64_t{1'000'000}}, std::pair{late, int64_t{6'000'000}}}) {
    std::size_t in_window = 0;
    const std::size_t n = task->count();
    for (std::size_t i = 0; i < n; ++i) {
      const int64_t offset = ((task->time(i) - phase) % kPeriod + kPeriod) % kPeriod;
      if (offset < kPeriod / 2) ++in_window;  // woke within 5 ms after its deadline
    }
    // Most, not all: a loaded machine may wake a task a few ms late now and then.
    EXPECT_GE(in_window * 4, n * 3) << in_window << " of " << n << " wake-ups within 5 ms after phase " << phase;
  }
}

}  // namespace
}  // namespace rack
