// rack-gui's reply matching (tools/gui/reply_matcher.h): a reply reaches the request it
// answers, or nobody. The hostile cases: more than 255 requests in flight to one
// mailbox, a late reply from a request that timed out (an executor replying late, or a
// peer replying with guessed numbers), a request sent into the reply mailbox.
#include "reply_matcher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>
#include <vector>

namespace rack::gui {
namespace {

constexpr int64_t kMs = 1'000'000;
constexpr uint32_t kLadar = 0x00030100;  // two destinations (component addresses)
constexpr uint32_t kMcl = 0x00040100;

TEST(ReplyMatcherTest, RequestsInFlightToOneMailboxNeverShareANumber) {
  ReplyMatcher m(10'000 * kMs);
  std::vector<uint8_t> seqs;
  for (uint64_t token = 0; token < 256; ++token) {
    const auto s = m.open(kLadar, token, 2000 * kMs, 0);
    ASSERT_TRUE(s.has_value()) << "request " << token;
    seqs.push_back(*s);
  }
  EXPECT_EQ(std::set<uint8_t>(seqs.begin(), seqs.end()).size(), 256u);
  // The 257th would share a number with a waiting request: refused, not sent.
  EXPECT_FALSE(m.open(kLadar, 256, 2000 * kMs, 0).has_value());
  EXPECT_EQ(m.refused(), 1u);
  // Another mailbox has its own numbers.
  EXPECT_TRUE(m.open(kMcl, 1000, 2000 * kMs, 0).has_value());
  // Answered in any order, each reply reaches its own request.
  std::vector<uint64_t> order(256);
  for (uint64_t i = 0; i < 256; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  for (const uint64_t token : order) {
    const auto r = m.match(kLadar, seqs[token], -6 /* DATA */);
    ASSERT_EQ(r.outcome, ReplyMatcher::Outcome::kAnswered);
    EXPECT_EQ(r.token, token);
  }
  EXPECT_EQ(m.waiting(), 1u);
  // Answered: a second reply with the same number is nobody's.
  EXPECT_EQ(m.match(kLadar, seqs[0], 0).outcome, ReplyMatcher::Outcome::kUnmatched);
}

// An executor that answers after the request's timeout: with one counter for every
// request, the 256th later request to that mailbox held the same number and took the
// stale reply as its own. Here the number stays in quarantine and the reply is dropped.
TEST(ReplyMatcherTest, ALateReplyIsDroppedNotTakenByALaterRequest) {
  ReplyMatcher m(20'000 * kMs);
  const auto slow = m.open(kLadar, 1, 2000 * kMs, 0);
  ASSERT_TRUE(slow.has_value());
  EXPECT_EQ(m.expire(1000 * kMs), std::vector<uint64_t>{});
  EXPECT_EQ(m.expire(2000 * kMs), std::vector<uint64_t>{1}) << "timed out at its deadline";
  // 600 more requests to the same mailbox, each answered at once: none gets its number.
  int64_t now = 2000 * kMs;
  for (uint64_t token = 100; token < 700; ++token) {
    const auto s = m.open(kLadar, token, now + 2000 * kMs, now);
    ASSERT_TRUE(s.has_value());
    EXPECT_NE(*s, *slow) << "request " << token << " got the number of the request that timed out";
    const auto r = m.match(kLadar, *s, 0);
    EXPECT_EQ(r.token, token);
    now += 10 * kMs;
  }
  // A request that is waiting when the late reply comes.
  const auto waiting = m.open(kLadar, 999, now + 2000 * kMs, now);
  ASSERT_TRUE(waiting.has_value());
  const auto late = m.match(kLadar, *slow, -1 /* ERROR */);
  EXPECT_EQ(late.outcome, ReplyMatcher::Outcome::kLate);
  EXPECT_EQ(m.late(), 1u);
  EXPECT_EQ(m.waiting(), 1u) << "the waiting request is still waiting";
  EXPECT_EQ(m.match(kLadar, *waiting, 0).token, 999u);
}

TEST(ReplyMatcherTest, TheQuarantineEndsAndAMailboxThatNeverAnswersRunsOutOfNumbers) {
  ReplyMatcher m(5000 * kMs);
  // A mailbox that never answers, asked 300 times within its quarantine: 256 numbers,
  // then refusals, never a number shared with a request that may still be answered.
  std::set<uint8_t> used;
  std::size_t refused = 0;
  for (uint64_t token = 0; token < 300; ++token) {
    const int64_t now = static_cast<int64_t>(token) * kMs;
    (void)m.expire(now);
    const auto s = m.open(kMcl, token, now + 100 * kMs, now);
    if (!s) {
      ++refused;
      continue;
    }
    EXPECT_TRUE(used.insert(*s).second) << "number " << int{*s} << " given twice";
  }
  EXPECT_EQ(used.size(), 256u);
  EXPECT_EQ(refused, 44u);
  EXPECT_EQ(m.refused(), 44u);
  // Once the quarantine is over, the numbers are free again.
  const int64_t later = 300 * kMs + 100 * kMs + 5000 * kMs;
  EXPECT_EQ(m.expire(later).size(), 56u) << "the requests opened last time out now";
  EXPECT_TRUE(m.open(kMcl, 1000, later + 100 * kMs, later).has_value());
}

TEST(ReplyMatcherTest, AReplyMustComeFromTheMailboxAskedAndBeAReply) {
  ReplyMatcher m(10'000 * kMs);
  const auto a = m.open(kLadar, 1, 2000 * kMs, 0);
  const auto b = m.open(kMcl, 2, 2000 * kMs, 0);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(*a, *b) << "each mailbox numbers its own requests";
  // A request (type > 0) with the right source and number answers nothing.
  EXPECT_EQ(m.match(kLadar, *a, 3 /* GET_STATUS */).outcome, ReplyMatcher::Outcome::kNotAReply);
  EXPECT_EQ(m.not_replies(), 1u);
  // From a third mailbox with the same number: nobody's.
  EXPECT_EQ(m.match(0x00050100, *a, 0).outcome, ReplyMatcher::Outcome::kUnmatched);
  EXPECT_EQ(m.match(kMcl, *b, 0).token, 2u);
  EXPECT_EQ(m.match(kLadar, *a, 0).token, 1u);
  // A number given back before it was sent is free again.
  const auto c = m.open(kLadar, 3, 2000 * kMs, 0);
  ASSERT_TRUE(c.has_value());
  m.cancel(kLadar, *c);
  EXPECT_EQ(m.waiting(), 0u);
  EXPECT_EQ(m.match(kLadar, *c, 0).outcome, ReplyMatcher::Outcome::kUnmatched);
}

}  // namespace
}  // namespace rack::gui
