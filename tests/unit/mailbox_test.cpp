// Mailbox: priority order, drop policy, sizes, timeouts, zero-copy peek, close/wake.
#include "rack/tims/mailbox.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <functional>
#include <thread>
#include <vector>

#include "test_support.h"

namespace rack::tims {
namespace {

using test::Tag;
using test::tag_header;
using test::Watchdog;

class MailboxTest : public ::testing::Test {
 protected:
  static constexpr Address kSelf = Address::make(0, classes::kTool, 1, 1);
  static constexpr Address kPeer = Address::make(0, classes::kTool, 2, 1);

  static SendStatus send_tag(Mailbox& m, uint32_t id, uint8_t priority) {
    const Tag t{id, 0};
    return m.try_send(tag_header(m.address(), kPeer, priority), {buffer_of(t)});
  }
  // Receives one message (non-blocking) and returns its tag id, or UINT32_MAX.
  static uint32_t recv_id(Mailbox& m, int64_t timeout_ns = Mailbox::kNonBlocking) {
    alignas(8) std::array<std::byte, 256> buf{};
    const auto r = m.receive(buf, timeout_ns);
    if (r.status != RecvStatus::kOk) return UINT32_MAX;
    EXPECT_EQ(r.length, sizeof(MessageHeader) + sizeof(Tag));
    Tag t;
    std::memcpy(&t, buf.data() + sizeof(MessageHeader), sizeof t);
    return t.id;
  }
  static std::vector<uint32_t> drain(Mailbox& m) {
    std::vector<uint32_t> ids;
    for (uint32_t id = recv_id(m); id != UINT32_MAX; id = recv_id(m)) ids.push_back(id);
    return ids;
  }
  // What a receive(kForever) in another thread returns when `release` (called once
  // that thread had time to block in it) wakes it.
  static RecvStatus blocked_receive_released_by(Mailbox& m, const std::function<void()>& release) {
    std::atomic<int> status{-1};
    std::thread reader([&] {
      alignas(8) std::array<std::byte, 128> buf{};
      status = static_cast<int>(m.receive(buf, Mailbox::kForever).status);
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    release();
    reader.join();
    return static_cast<RecvStatus>(status.load());
  }
};

TEST_F(MailboxTest, ReadsHigherPriorityFirstAndFifoWithinAPriority) {
  Mailbox m(kSelf, 8, 128);
  ASSERT_EQ(send_tag(m, 1, 1), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 2, 5), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 3, 1), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 4, 5), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 5, 3), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 6, 1), SendStatus::kOk);
  EXPECT_EQ(m.queued(), 6u);
  EXPECT_EQ(drain(m), (std::vector<uint32_t>{2, 4, 5, 1, 3, 6}));
  EXPECT_EQ(m.queued(), 0u);
  const auto c = m.counters();
  EXPECT_EQ(c.sent, 6u);
  EXPECT_EQ(c.received, 6u);
}

TEST_F(MailboxTest, FifoSurvivesSlotReuse) {
  // Slots are reused out of order; order must follow send order, not slot index.
  Mailbox m(kSelf, 3, 128);
  ASSERT_EQ(send_tag(m, 1, 2), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 2, 2), SendStatus::kOk);
  EXPECT_EQ(recv_id(m), 1u);                      // frees slot 0
  ASSERT_EQ(send_tag(m, 3, 2), SendStatus::kOk);  // lands in slot 0
  ASSERT_EQ(send_tag(m, 4, 2), SendStatus::kOk);  // slot 2
  EXPECT_EQ(drain(m), (std::vector<uint32_t>{2, 3, 4}));
}

TEST_F(MailboxTest, FullDropsOldestOfLowestPriorityWhenNotAboveNewOne) {
  Mailbox m(kSelf, 3, 128);
  ASSERT_EQ(send_tag(m, 1, 2), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 2, 1), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 3, 1), SendStatus::kOk);
  // Full. The victim is the oldest of priority 1 (id 2), even for a same-priority send.
  EXPECT_EQ(send_tag(m, 4, 1), SendStatus::kOkDroppedOlder);
  EXPECT_EQ(m.counters().dropped, 1u);
  EXPECT_EQ(m.queued(), 3u);
  // A higher-priority send drops the oldest remaining priority-1 message (id 3).
  EXPECT_EQ(send_tag(m, 5, 9), SendStatus::kOkDroppedOlder);
  EXPECT_EQ(m.counters().dropped, 2u);
  EXPECT_EQ(m.counters().refused, 0u);
  EXPECT_EQ(drain(m), (std::vector<uint32_t>{5, 1, 4}));
}

TEST_F(MailboxTest, FullRefusesWhenEveryQueuedMessageHasHigherPriority) {
  Mailbox m(kSelf, 2, 128);
  ASSERT_EQ(send_tag(m, 1, 5), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 2, 7), SendStatus::kOk);
  EXPECT_EQ(send_tag(m, 3, 4), SendStatus::kFull);
  EXPECT_EQ(send_tag(m, 4, 0), SendStatus::kFull);
  const auto c = m.counters();
  EXPECT_EQ(c.refused, 2u);
  EXPECT_EQ(c.dropped, 0u);
  EXPECT_EQ(c.sent, 2u);
  EXPECT_EQ(drain(m), (std::vector<uint32_t>{2, 1}));
  EXPECT_FALSE(delivered(SendStatus::kFull));
  EXPECT_TRUE(delivered(SendStatus::kOkDroppedOlder));
}

TEST_F(MailboxTest, MessageLargerThanASlotIsRefused) {
  Mailbox m(kSelf, 2, 64);  // 16-byte header + 48 bytes of body fit exactly
  ASSERT_EQ(m.slot_size(), 64u);
  std::array<std::byte, 49> body{};
  const ConstBuffer fits{body.data(), 48};
  EXPECT_EQ(m.try_send(make_header(kSelf, kPeer, msg::kData, 0, 0, 48), {fits}), SendStatus::kOk);
  const ConstBuffer too_big{body.data(), 49};
  EXPECT_EQ(m.try_send(make_header(kSelf, kPeer, msg::kData, 0, 0, 49), {too_big}), SendStatus::kTooLarge);
  EXPECT_EQ(m.counters().too_large, 1u);
  EXPECT_EQ(m.queued(), 1u);
}

TEST_F(MailboxTest, HeaderLengthDisagreeingWithTheBodyIsRefused) {
  Mailbox m(kSelf, 2, 128);
  const Tag t{1, 0};
  // The header claims 4 body bytes more than are given.
  EXPECT_NE(m.try_send(make_header(kSelf, kPeer, msg::kData, 0, 0, sizeof t + 4), {buffer_of(t)}), SendStatus::kOk);
  EXPECT_EQ(m.queued(), 0u);
}

TEST_F(MailboxTest, ReceiveTimesOutOrReturnsEmptyWhenNothingIsQueued) {
  Watchdog dog;
  Mailbox m(kSelf, 2, 128);
  alignas(8) std::array<std::byte, 128> buf{};
  EXPECT_EQ(m.receive(buf, Mailbox::kNonBlocking).status, RecvStatus::kEmpty);
  const int64_t t0 = rt::monotonic_ns();
  EXPECT_EQ(m.receive(buf, 20 * rt::kNsPerMs).status, RecvStatus::kTimeout);
  // Behaviour (not timing): a timed receive does wait, at least roughly its timeout.
  EXPECT_GE(rt::monotonic_ns() - t0, 10 * rt::kNsPerMs);
  EXPECT_EQ(m.peek(Mailbox::kNonBlocking).status, RecvStatus::kEmpty);
  EXPECT_FALSE(m.wait(Mailbox::kNonBlocking));
}

TEST_F(MailboxTest, BlockingReceiveIsWokenBySendFromAnotherThread) {
  Watchdog dog;
  Mailbox m(kSelf, 4, 128);
  std::thread sender([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    EXPECT_EQ(send_tag(m, 42, 3), SendStatus::kOk);
  });
  EXPECT_EQ(recv_id(m, Mailbox::kForever), 42u);
  sender.join();
}

TEST_F(MailboxTest, TooSmallBufferConsumesTheMessageAndCountsIt) {
  Mailbox m(kSelf, 2, 128);
  std::array<std::byte, 32> body{};
  body[0] = std::byte{0x5A};
  const ConstBuffer part{body.data(), body.size()};
  ASSERT_EQ(m.try_send(make_header(kSelf, kPeer, msg::kData, 0, 7, body.size()), {part}), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 2, 0), SendStatus::kOk);
  alignas(8) std::array<std::byte, 20> small{};
  const auto r = m.receive(small, Mailbox::kNonBlocking);
  EXPECT_EQ(r.status, RecvStatus::kTooSmall);
  EXPECT_EQ(r.header.length, sizeof(MessageHeader) + body.size());  // says what it was
  EXPECT_EQ(r.header.seq, 7);
  EXPECT_EQ(m.counters().truncated, 1u);
  EXPECT_EQ(m.counters().received, 0u);
  // Consumed: the next receive gets the next message.
  EXPECT_EQ(m.queued(), 1u);
  EXPECT_EQ(recv_id(m), 2u);
}

TEST_F(MailboxTest, PeekIsZeroCopyAndHoldsTheSlotUntilPeekEnd) {
  Mailbox m(kSelf, 1, 128);  // one slot: any reuse would be visible
  ASSERT_EQ(send_tag(m, 7, 1), SendStatus::kOk);
  const auto p = m.peek(Mailbox::kNonBlocking);
  ASSERT_EQ(p.status, RecvStatus::kOk);
  ASSERT_NE(p.header, nullptr);
  const MessageHeader* held = p.header;
  const std::byte* body = p.body.data();
  ASSERT_EQ(p.body.size(), sizeof(Tag));
  EXPECT_EQ(p.header->length, sizeof(MessageHeader) + sizeof(Tag));

  // The slot is being read: a send of any priority cannot take it.
  EXPECT_EQ(send_tag(m, 8, 255), SendStatus::kFull);
  EXPECT_EQ(m.counters().refused, 1u);
  Tag t;
  std::memcpy(&t, body, sizeof t);
  EXPECT_EQ(t.id, 7u);
  EXPECT_EQ(held->priority, 1);

  // A second peek without peek_end gets the same message in place.
  const auto again = m.peek(Mailbox::kNonBlocking);
  EXPECT_EQ(again.status, RecvStatus::kOk);
  EXPECT_EQ(again.header, held);
  EXPECT_EQ(again.body.data(), body);

  m.peek_end();
  EXPECT_EQ(m.counters().received, 1u);
  EXPECT_EQ(send_tag(m, 9, 1), SendStatus::kOk);
  EXPECT_EQ(recv_id(m), 9u);
  m.peek_end();  // without a peek: harmless
  EXPECT_EQ(m.counters().received, 2u);
}

TEST_F(MailboxTest, PeekedSlotIsNotAVictimOfTheDropPolicy) {
  Mailbox m(kSelf, 2, 128);
  ASSERT_EQ(send_tag(m, 1, 0), SendStatus::kOk);
  ASSERT_EQ(send_tag(m, 2, 0), SendStatus::kOk);
  const auto p = m.peek(Mailbox::kNonBlocking);
  ASSERT_EQ(p.status, RecvStatus::kOk);
  const std::byte* body = p.body.data();
  // Full: the only victim allowed is the queued (not peeked) message 2.
  EXPECT_EQ(send_tag(m, 3, 5), SendStatus::kOkDroppedOlder);
  EXPECT_EQ(send_tag(m, 4, 5), SendStatus::kOkDroppedOlder);
  Tag t;
  std::memcpy(&t, body, sizeof t);
  EXPECT_EQ(t.id, 1u);
  m.peek_end();
  EXPECT_EQ(drain(m), (std::vector<uint32_t>{4}));
  EXPECT_EQ(m.counters().dropped, 2u);
}

TEST_F(MailboxTest, CloseRefusesSendsDrainsQueueThenReportsClosed) {
  Watchdog dog;
  Mailbox m(kSelf, 4, 128);
  ASSERT_EQ(send_tag(m, 1, 0), SendStatus::kOk);
  m.close();
  EXPECT_EQ(send_tag(m, 2, 0), SendStatus::kClosed);
  EXPECT_EQ(recv_id(m), 1u);
  alignas(8) std::array<std::byte, 128> buf{};
  EXPECT_EQ(m.receive(buf, Mailbox::kForever).status, RecvStatus::kClosed);
  EXPECT_EQ(m.peek(Mailbox::kForever).status, RecvStatus::kClosed);
  m.reopen();
  EXPECT_EQ(send_tag(m, 3, 0), SendStatus::kOk);
  EXPECT_EQ(recv_id(m), 3u);
}

TEST_F(MailboxTest, CloseWakesABlockedReceiver) {
  Watchdog dog;
  Mailbox m(kSelf, 4, 128);
  EXPECT_EQ(blocked_receive_released_by(m, [&] { m.close(); }), RecvStatus::kClosed);
}

TEST_F(MailboxTest, WakeReturnsABlockedReceiverWithoutAMessage) {
  Watchdog dog;
  Mailbox m(kSelf, 4, 128);
  EXPECT_EQ(blocked_receive_released_by(m, [&] { m.wake(); }), RecvStatus::kTimeout);
  EXPECT_EQ(m.counters().received, 0u);

  // wait() returns too, and says nothing is queued.
  std::atomic<int> waited{-1};
  std::thread waiter([&] { waited = m.wait(Mailbox::kForever) ? 1 : 0; });
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  m.wake();
  waiter.join();
  EXPECT_EQ(waited.load(), 0);
  // A queued message is still delivered normally.
  ASSERT_EQ(send_tag(m, 5, 0), SendStatus::kOk);
  EXPECT_TRUE(m.wait(Mailbox::kForever));
  EXPECT_EQ(recv_id(m), 5u);
}

TEST_F(MailboxTest, TrySendBytesQueuesACompleteMessage) {
  Mailbox m(kSelf, 2, 128);
  alignas(8) std::array<std::byte, sizeof(MessageHeader) + sizeof(Tag)> raw{};
  const MessageHeader h = tag_header(kSelf, kPeer, 3);
  const Tag t{77, 0};
  std::memcpy(raw.data(), &h, sizeof h);
  std::memcpy(raw.data() + sizeof h, &t, sizeof t);
  EXPECT_EQ(m.try_send_bytes(raw), SendStatus::kOk);
  EXPECT_EQ(m.try_send_bytes(std::span<const std::byte>(raw).first(10)), SendStatus::kTooLarge);
  EXPECT_EQ(recv_id(m), 77u);
}

// Many senders, one reader: every message arrives whole (all words of a body equal),
// and the counters add up: sent == received + dropped.
TEST_F(MailboxTest, ConcurrentSendersNeverTearAMessage) {
  Watchdog dog;
  constexpr int kSenders = 3;
  constexpr uint32_t kPerSender = 3000;
  constexpr std::size_t kWords = 16;
  Mailbox m(kSelf, 8, 256);
  std::atomic<int> running{kSenders};
  std::vector<std::thread> senders;
  for (int s = 0; s < kSenders; ++s) {
    senders.emplace_back([&, s] {
      std::array<uint64_t, kWords> body{};
      for (uint32_t i = 0; i < kPerSender; ++i) {
        body.fill((uint64_t{static_cast<uint32_t>(s)} << 32) | i);
        const auto st = m.try_send(make_header(kSelf, kPeer, msg::kData, static_cast<uint8_t>(i % 3), 0, sizeof body),
                                   {buffer_of(body)});
        EXPECT_TRUE(st == SendStatus::kOk || st == SendStatus::kOkDroppedOlder || st == SendStatus::kFull);
        if (i % 64 == 0) std::this_thread::yield();
      }
      running.fetch_sub(1);
    });
  }
  uint64_t got = 0, torn = 0;
  alignas(8) std::array<std::byte, 256> buf{};
  for (;;) {
    const auto r = m.receive(buf, 2 * rt::kNsPerMs);
    if (r.status == RecvStatus::kOk) {
      ++got;
      std::array<uint64_t, kWords> body{};
      ASSERT_EQ(r.length, sizeof(MessageHeader) + sizeof body);
      std::memcpy(body.data(), buf.data() + sizeof(MessageHeader), sizeof body);
      for (uint64_t w : body) torn += w != body[0] ? 1u : 0u;
      continue;
    }
    if (running.load() == 0 && m.queued() == 0) break;
  }
  for (auto& t : senders) t.join();
  EXPECT_EQ(torn, 0u);
  const auto c = m.counters();
  EXPECT_EQ(c.sent, c.received + c.dropped);
  EXPECT_EQ(c.received, got);
  EXPECT_EQ(c.sent + c.refused, uint64_t{kSenders} * kPerSender);
}

}  // namespace
}  // namespace rack::tims
