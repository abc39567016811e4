// ExecTimeStats: the log-linear histogram of how long a task's loop() ran, and its
// report through GET_STATS for a triggered task (which has no wake-up latency).
#include <gtest/gtest.h>

#include <chrono>

#include "rack/rt/exec_time_stats.h"
#include "test_support.h"

namespace rack::test {
namespace {

using rt::ExecTimeStats;

TEST(ExecTimeStatsTest, BucketsAreExactBelow64NsAndWithin3PercentAbove) {
  for (uint64_t v = 0; v < 64; ++v) {
    EXPECT_EQ(ExecTimeStats::bucket_of(v), v);
    EXPECT_EQ(ExecTimeStats::lower_of(v), v);
  }
  // Every bucket holds [lower_of(i), lower_of(i + 1)); its width is at most 1/32 of
  // its lower edge above 64 ns.
  for (std::size_t i = 0; i + 1 < ExecTimeStats::kBuckets; ++i) {
    const uint64_t lo = ExecTimeStats::lower_of(i), hi = ExecTimeStats::lower_of(i + 1);
    ASSERT_LT(lo, hi) << i;
    EXPECT_EQ(ExecTimeStats::bucket_of(lo), i);
    EXPECT_EQ(ExecTimeStats::bucket_of(hi - 1), i);
    if (lo >= 64) {
      EXPECT_LE(static_cast<double>(hi - lo) / static_cast<double>(lo), 1.0 / 32.0) << i;
    }
  }
  // Anything beyond the range counts in the last bucket.
  EXPECT_EQ(ExecTimeStats::bucket_of(UINT64_MAX), ExecTimeStats::kBuckets - 1);
}

TEST(ExecTimeStatsTest, PercentilesOfKnownDurations) {
  auto s = std::make_unique<ExecTimeStats>();
  EXPECT_EQ(s->summary().samples, 0U);
  // 98 cycles of 20 us, one of 5 ms, one of 200 ms (an MCL update beside Scan2D's).
  for (int i = 0; i < 98; ++i) s->record(20'000);
  s->record(5'000'000);
  s->record(200'000'000);
  const rt::ExecTimeSummary sum = s->summary();
  EXPECT_EQ(sum.samples, 100U);
  EXPECT_NEAR(static_cast<double>(sum.p50_ns), 20'000.0, 20'000.0 / 32.0);
  EXPECT_GE(sum.p50_ns, 20'000);
  // p99: the 99th of 100 sorted: 5 ms (within the bucket's 3 %).
  EXPECT_NEAR(static_cast<double>(sum.p99_ns), 5e6, 5e6 / 32.0);
  EXPECT_EQ(sum.max_ns, 200'000'000);
  EXPECT_EQ(sum.mean_ns, (98 * 20'000LL + 5'000'000LL + 200'000'000LL) / 100);
  // A negative duration (a clock step) counts as 0, not as a huge value.
  s->record(-5);
  EXPECT_EQ(s->summary().samples, 101U);
  EXPECT_EQ(s->summary().max_ns, 200'000'000);
}

// A triggered task (the Monitor, woken by the Generator's samples) reports how long
// its loop() ran in GET_STATS, as a periodic one does; it has no wake-up latency.
TEST(ExecTimeStatsTest, TriggeredTaskReportsItsExecutionTime) {
  Watchdog watchdog;
  HostUnderTest h(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 5, ring: 50}
  - name: mon
    class: Monitor
    autostart: true
    params: {source: gen, silence_ms: 1000}
)");
  const auto mon = h.address_of("mon");
  const auto gen = h.address_of("gen");
  ASSERT_TRUE(eventually([&] { return h.stats(mon).exec_samples >= 20; })) << h.log();
  const wire::StatsReply st = h.stats(mon);
  EXPECT_EQ(st.data_task, static_cast<uint8_t>(DataTaskMode::kTriggered));
  EXPECT_EQ(st.data.samples, 0U);  // no wake-up latency for a triggered task
  EXPECT_GT(st.exec_p50_ns, 0);
  EXPECT_GE(st.exec_p99_ns, st.exec_p50_ns);
  EXPECT_GE(st.exec_max_ns, st.exec_p99_ns);
  EXPECT_GT(h.stats(gen).exec_samples, 0U);  // periodic tasks too
}

}  // namespace
}  // namespace rack::test
