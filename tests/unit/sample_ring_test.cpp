// SampleRing: lookup rules, wrap-around, and a concurrent writer/reader.
#include "rack/core/sample_ring.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <thread>

#include "test_support.h"

namespace rack {
namespace {

class SampleRingTest : public ::testing::Test {
 protected:
  struct Payload {
    uint64_t a = 0;
    uint64_t b = 0;
  };
  // Writes samples at times t0, t0+step, ... with payload a = index.
  static void fill(SampleRing& ring, int n, int64_t t0, int64_t step) {
    for (int i = 0; i < n; ++i) {
      const Payload p{static_cast<uint64_t>(i), ~static_cast<uint64_t>(i)};
      EXPECT_EQ(ring.write(t0 + i * step, &p), static_cast<uint64_t>(i));
    }
  }
  // The sequence number found for `time`, or -1 with `result` set.
  static int64_t lookup(const SampleRing& ring, int64_t time, int64_t max_ahead, RingLookup& result) {
    wire::SampleHeader h;
    Payload p;
    result = ring.read(time, max_ahead, h, &p);
    if (result != RingLookup::kOk) return -1;
    EXPECT_EQ(p.a, h.sequence);
    EXPECT_EQ(p.b, ~h.sequence);
    return static_cast<int64_t>(h.sequence);
  }
  static int64_t lookup(const SampleRing& ring, int64_t time, int64_t max_ahead = 0) {
    RingLookup r{};
    const int64_t s = lookup(ring, time, max_ahead, r);
    EXPECT_EQ(r, RingLookup::kOk) << "time " << time << ": " << describe(r);
    return s;
  }
};

TEST_F(SampleRingTest, EmptyRingReportsEmpty) {
  SampleRing ring(8, sizeof(Payload));
  RingLookup r{};
  EXPECT_EQ(lookup(ring, 0, 0, r), -1);
  EXPECT_EQ(r, RingLookup::kEmpty);
  EXPECT_EQ(lookup(ring, 1000, 0, r), -1);
  EXPECT_EQ(r, RingLookup::kEmpty);
  EXPECT_EQ(ring.written(), 0u);
}

TEST_F(SampleRingTest, TimeZeroGivesTheNewestSample) {
  SampleRing ring(8, sizeof(Payload));
  fill(ring, 5, 100, 100);
  EXPECT_EQ(lookup(ring, 0), 4);
  Payload p{99, ~uint64_t{99}};
  (void)ring.write(600, &p);
  wire::SampleHeader h;
  Payload got;
  ASSERT_EQ(ring.read(0, 0, h, &got), RingLookup::kOk);
  EXPECT_EQ(h.sequence, 5u);
  EXPECT_EQ(h.time_ns, 600);
  EXPECT_EQ(got.a, 99u);
}

TEST_F(SampleRingTest, FindsTheSampleNearestInTimeAndEarlierOnTies) {
  SampleRing ring(16, sizeof(Payload));
  fill(ring, 5, 100, 100);  // times 100, 200, 300, 400, 500 -> sequences 0..4
  EXPECT_EQ(lookup(ring, 100), 0);
  EXPECT_EQ(lookup(ring, 300), 2);
  EXPECT_EQ(lookup(ring, 349), 2);
  EXPECT_EQ(lookup(ring, 351), 3);
  EXPECT_EQ(lookup(ring, 350), 2);  // tie: the earlier sample
  EXPECT_EQ(lookup(ring, 150), 0);  // tie at the oldest
  EXPECT_EQ(lookup(ring, 450), 3);  // tie before the newest
  EXPECT_EQ(lookup(ring, 201), 1);
  EXPECT_EQ(lookup(ring, 500), 4);
}

TEST_F(SampleRingTest, TooOldAndTooNewAreErrors) {
  SampleRing ring(16, sizeof(Payload));
  fill(ring, 5, 100, 100);
  RingLookup r{};
  EXPECT_EQ(lookup(ring, 99, 50, r), -1);
  EXPECT_EQ(r, RingLookup::kTooOld);
  // Up to newest + max_ahead gives the newest; beyond is too new.
  EXPECT_EQ(lookup(ring, 520, 50), 4);
  EXPECT_EQ(lookup(ring, 550, 50), 4);
  EXPECT_EQ(lookup(ring, 551, 50, r), -1);
  EXPECT_EQ(r, RingLookup::kTooNew);
  EXPECT_EQ(lookup(ring, 501, 0, r), -1);
  EXPECT_EQ(r, RingLookup::kTooNew);
  EXPECT_NE(describe(RingLookup::kTooNew), nullptr);
}

TEST_F(SampleRingTest, WrapAroundKeepsTheLastCapacityMinusOneSamples) {
  SampleRing ring(4, sizeof(Payload));
  fill(ring, 10, 100, 100);  // sequences 0..9 at times 100..1000
  EXPECT_EQ(ring.written(), 10u);
  EXPECT_EQ(lookup(ring, 0), 9);
  // Held: sequences 7, 8, 9 (times 800, 900, 1000).
  EXPECT_EQ(lookup(ring, 800), 7);
  EXPECT_EQ(lookup(ring, 900), 8);
  EXPECT_EQ(lookup(ring, 1000), 9);
  EXPECT_EQ(lookup(ring, 860), 8);
  RingLookup r{};
  EXPECT_EQ(lookup(ring, 799, 0, r), -1);
  EXPECT_EQ(r, RingLookup::kTooOld);
  EXPECT_EQ(lookup(ring, 700, 0, r), -1);
  EXPECT_EQ(r, RingLookup::kTooOld);
  EXPECT_EQ(lookup(ring, 100, 0, r), -1);
  EXPECT_EQ(r, RingLookup::kTooOld);
  // By sequence: overwritten ones are gone.
  wire::SampleHeader h;
  Payload p;
  EXPECT_TRUE(ring.read_sequence(9, h, &p));
  EXPECT_EQ(p.a, 9u);
  EXPECT_FALSE(ring.read_sequence(5, h, &p));
  EXPECT_FALSE(ring.read_sequence(10, h, &p));  // not written yet
}

TEST_F(SampleRingTest, PayloadNotAMultipleOfEightBytesIsKeptExactly) {
  SampleRing ring(4, 11);
  std::array<unsigned char, 11> in{};
  for (std::size_t i = 0; i < in.size(); ++i) in[i] = static_cast<unsigned char>(0xA0 + i);
  (void)ring.write(5, in.data());
  std::array<unsigned char, 16> out{};
  out.fill(0xEE);
  wire::SampleHeader h;
  ASSERT_EQ(ring.read(0, 0, h, out.data()), RingLookup::kOk);
  for (std::size_t i = 0; i < in.size(); ++i) EXPECT_EQ(out[i], in[i]) << i;
  for (std::size_t i = in.size(); i < out.size(); ++i) EXPECT_EQ(out[i], 0xEE) << "wrote past the payload";
}

// A writer and a reader on two threads: every sample the reader gets is whole (all
// payload words carry the same sequence number, which matches the header).
TEST_F(SampleRingTest, ConcurrentWriterAndReaderNeverSeeATornSample) {
  test::Watchdog dog;
  constexpr std::size_t kWords = 12;
  constexpr uint64_t kSamples = 300'000;
  SampleRing ring(4, kWords * sizeof(uint64_t));  // small: the writer laps the reader often
  std::atomic<bool> done{false};
  std::thread writer([&] {
    std::array<uint64_t, kWords> p{};
    for (uint64_t s = 0; s < kSamples; ++s) {
      p.fill(s);
      EXPECT_EQ(ring.write(static_cast<int64_t>(s + 1) * 10, p.data()), s);
    }
    done.store(true, std::memory_order_release);
  });
  uint64_t ok = 0, torn = 0, contended = 0, last_newest = 0;
  bool monotonic = true;
  std::array<uint64_t, kWords> p{};
  uint64_t i = 0, after_done = 0;
  // Until the writer is done and then some: under load every read while it writes may be
  // contended, and the reads after it finished must then succeed.
  while (!done.load(std::memory_order_acquire) || i < 1000 || after_done < 10) {
    ++i;
    if (done.load(std::memory_order_acquire)) ++after_done;
    wire::SampleHeader h;
    const uint64_t written = ring.written();
    // Alternate newest and a time lookup near the head.
    const int64_t t = (i % 2 == 0 || written < 3) ? 0 : static_cast<int64_t>(written - 1) * 10;
    const RingLookup r = ring.read(t, 1000, h, p.data());
    if (r == RingLookup::kContended || r == RingLookup::kTooOld) {
      ++contended;  // the writer lapped us: allowed, never torn
      continue;
    }
    if (r == RingLookup::kEmpty) continue;
    ASSERT_EQ(r, RingLookup::kOk) << describe(r);
    ++ok;
    for (uint64_t w : p) torn += w != h.sequence ? 1u : 0u;
    if (h.time_ns != static_cast<int64_t>(h.sequence + 1) * 10) ++torn;
    if (t == 0) {
      if (h.sequence < last_newest) monotonic = false;
      last_newest = h.sequence;
    }
  }
  writer.join();
  // With the writer gone the newest sample reads whole. (During the run every read can
  // be lapped when the writer's CPU is fast and the reader's is loaded: then the loop
  // above sees no kOk at all, which is allowed.)
  {
    wire::SampleHeader h;
    ASSERT_EQ(ring.read(0, 1000, h, p.data()), RingLookup::kOk);
    ++ok;
    for (uint64_t w : p) torn += w != h.sequence ? 1u : 0u;
    EXPECT_EQ(h.sequence, kSamples - 1);
  }
  EXPECT_EQ(torn, 0u);
  EXPECT_TRUE(monotonic) << "the newest sample went backwards";
  RecordProperty("whole_reads", static_cast<int>(ok));
  RecordProperty("contended_reads", static_cast<int>(contended));
}

}  // namespace
}  // namespace rack
