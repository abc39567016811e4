// rackctl hz/bw's rolling statistics and the unit formatting of their numbers.
#include <gtest/gtest.h>

#include <string>

#include "stream_stats.h"

namespace rack::tools {
namespace {

TEST(StreamStatsTest, NoReportBeforeTwoSamples) {
  StreamStats s(10);
  EXPECT_FALSE(s.report());
  s.add(1'000'000'000, 100);
  EXPECT_FALSE(s.report());
  s.add(1'100'000'000, 100);
  ASSERT_TRUE(s.report());
  EXPECT_EQ(s.report()->samples, 2u);
}

TEST(StreamStatsTest, RegularStreamHasItsRateAndNoSpread) {
  StreamStats s(100);
  for (int i = 0; i < 50; ++i) s.add(int64_t{i} * 10'000'000, 88);  // 100 Hz, 88 bytes
  const auto r = s.report();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->samples, 50u);
  EXPECT_NEAR(r->rate_hz, 100.0, 1e-9);
  EXPECT_NEAR(r->period_min_s, 0.01, 1e-12);
  EXPECT_NEAR(r->period_max_s, 0.01, 1e-12);
  EXPECT_NEAR(r->period_std_s, 0.0, 1e-9);
  EXPECT_NEAR(r->bytes_per_s, 8800.0, 1e-6);
  EXPECT_EQ(r->size_min_bytes, 88u);
  EXPECT_EQ(r->size_max_bytes, 88u);
}

TEST(StreamStatsTest, WindowKeepsOnlyTheLastSamples) {
  StreamStats s(4);
  // Slow at first (1 s apart), then four samples 0.1 s apart: only those count.
  int64_t t = 0;
  for (int i = 0; i < 5; ++i) s.add(t += 1'000'000'000, 10);
  for (int i = 0; i < 4; ++i) s.add(t += 100'000'000, 1000);
  const auto r = s.report();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->samples, 4u);
  EXPECT_NEAR(r->rate_hz, 10.0, 1e-9);
  EXPECT_NEAR(r->period_max_s, 0.1, 1e-12);
  EXPECT_EQ(r->size_min_bytes, 1000u);
}

TEST(StreamStatsTest, JitterShowsInMinMaxAndStd) {
  StreamStats s(10);
  // Periods alternate 8 ms and 12 ms: mean 10 ms, std 2 ms.
  int64_t t = 0;
  s.add(t, 1);
  for (int i = 0; i < 8; ++i) s.add(t += (i % 2 == 0 ? 8'000'000 : 12'000'000), i % 2 == 0 ? 100 : 300);
  const auto r = s.report();
  ASSERT_TRUE(r);
  EXPECT_NEAR(r->period_min_s, 0.008, 1e-12);
  EXPECT_NEAR(r->period_max_s, 0.012, 1e-12);
  EXPECT_NEAR(r->period_mean_s, 0.010, 1e-12);
  EXPECT_NEAR(r->period_std_s, 0.002, 1e-9);
  EXPECT_EQ(r->size_min_bytes, 1u);
  EXPECT_EQ(r->size_max_bytes, 300u);
  // 4 x 100 + 4 x 300 bytes after the first sample, over 80 ms.
  EXPECT_NEAR(r->bytes_per_s, 1600.0 / 0.08, 1e-6);
}

TEST(StreamStatsTest, SamplesAtTheSameInstantGiveNoRate) {
  StreamStats s(10);
  s.add(5, 10);
  s.add(5, 10);
  const auto r = s.report();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->rate_hz, 0.0);
  EXPECT_EQ(r->bytes_per_s, 0.0);
}

TEST(StreamStatsTest, NumbersHaveUnitsAndThreeDigits) {
  EXPECT_EQ(seconds_text(0.0987654), "98.8 ms");
  EXPECT_EQ(seconds_text(1.5), "1.50 s");
  EXPECT_EQ(seconds_text(12e-6), "12.0 us");
  EXPECT_EQ(seconds_text(0.0), "0.00 us");
  EXPECT_EQ(hertz_text(9.99966), "10.0 Hz");
  EXPECT_EQ(seconds_text(0.99999), "1.00 s");
  EXPECT_EQ(bytes_text(1000), "0.98 KiB");
  EXPECT_EQ(hertz_text(1200.0), "1.20 kHz");
  EXPECT_EQ(bytes_text(812), "812 B");
  EXPECT_EQ(bytes_text(1280), "1.25 KiB");
  EXPECT_EQ(bytes_text(3.4 * 1024 * 1024), "3.40 MiB");
  StreamReport r;
  r.samples = 3;
  r.rate_hz = 10.0;
  r.period_min_s = 0.099;
  r.period_max_s = 0.101;
  r.period_mean_s = 0.1;
  r.period_std_s = 0.001;
  EXPECT_EQ(hz_line(r), "rate 10.0 Hz  period min 99.0 ms, max 101 ms, mean 100 ms, std 1.00 ms  (window 3 samples)");
}

// The executor's latency histogram ends in an open bucket from 10 ms on; a percentile
// there comes back as its upper edge (10.001 ms) and must not read as a measurement.
TEST(StreamStatsTest, PercentileInTheOpenBucketReadsAsAtLeast) {
  constexpr int64_t kOpen = 10'000'000;
  EXPECT_EQ(percentile_text(10'001'000, 25'000'000, kOpen), ">= 10.0 ms");
  EXPECT_TRUE(in_open_bucket(10'001'000, 25'000'000, kOpen));
  EXPECT_EQ(percentile_text(37'000, 25'000'000, kOpen), "37.0 us");
  EXPECT_EQ(percentile_text(9'999'000, 25'000'000, kOpen), "10.0 ms");  // a measured 9.999 ms, rounded
  // Capped by an exact max inside the open bucket: the max itself, a real value.
  EXPECT_FALSE(in_open_bucket(10'000'500, 10'000'500, kOpen));
  EXPECT_EQ(percentile_text(10'000'500, 10'000'500, kOpen), "10.0 ms");
}

}  // namespace
}  // namespace rack::tools
