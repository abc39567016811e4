// Router (local delivery, unknown addresses, uplink) and Endpoint (RPC matching).
#include "rack/components/class_ids.h"
#include "rack/tims/router.h"

#include <gtest/gtest.h>

#include <array>
#include <functional>
#include <stdexcept>
#include <thread>

#include "rack/tims/endpoint.h"
#include "test_support.h"

namespace rack::tims {
namespace {

using test::Tag;
using test::Watchdog;

class RouterTest : public ::testing::Test {
 protected:
  static constexpr uint8_t kSys = 0;
  static constexpr Address kClient = Address::make(kSys, classes::kTool, 1, 1);
  static constexpr Address kServer = Address::make(kSys, class_ids::kProbe, 1, 0);
  static constexpr Address kOther = Address::make(kSys, class_ids::kProbe, 2, 0);
  static constexpr Address kUnknown = Address::make(kSys, class_ids::kGenerator, 9, 0);

  void SetUp() override {
    router_.add(client_box_);
    router_.add(server_box_);
  }
  void TearDown() override {
    router_.remove(client_box_.address());
    router_.remove(server_box_.address());
  }

  Router router_{kSys};
  Mailbox client_box_{kClient, 8, 512};
  Mailbox server_box_{kServer, 8, 512};
  std::array<std::byte, 512> buf_{};
};

TEST_F(RouterTest, DeliversToALocalMailbox) {
  const Tag t{11, 0};
  EXPECT_EQ(router_.send(test::tag_header(kServer, kClient, 1), {buffer_of(t)}), SendStatus::kOk);
  EXPECT_EQ(router_.find(kServer), &server_box_);
  const auto r = server_box_.receive(buf_, Mailbox::kNonBlocking);
  ASSERT_EQ(r.status, RecvStatus::kOk);
  EXPECT_EQ(r.header.source(), kClient);
  Tag got;
  std::memcpy(&got, buf_.data() + sizeof(MessageHeader), sizeof got);
  EXPECT_EQ(got.id, 11u);
  EXPECT_EQ(router_.counters().delivered_local, 1u);
}

TEST_F(RouterTest, DuplicateAddressIsRejectedAndRemoveForgetsTheMailbox) {
  Mailbox twin(kServer, 2, 64);
  EXPECT_THROW(router_.add(twin), std::invalid_argument);
  router_.remove(kServer);
  EXPECT_EQ(router_.find(kServer), nullptr);
  router_.add(twin);  // the address is free again
  EXPECT_EQ(router_.find(kServer), &twin);
  router_.remove(kServer);
  router_.add(server_box_);
}

TEST_F(RouterTest, RequestToAnUnknownMailboxIsAnsweredNotAvailable) {
  Endpoint ep(router_, client_box_, 5);
  const auto r = ep.call(kUnknown, msg::kGetStatus, buf_, test::kCallTimeoutNs);
  ASSERT_EQ(r.status, CallStatus::kOk);
  EXPECT_EQ(r.reply.type, msg::kNotAvailable);
  EXPECT_EQ(r.reply.source(), kUnknown);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(router_.counters().not_available, 1u);
  EXPECT_EQ(router_.counters().unroutable, 0u);
}

TEST_F(RouterTest, ReplyOrNotificationToAnUnknownMailboxIsDroppedAndCounted) {
  const Tag t{1, 0};
  EXPECT_EQ(router_.send(test::tag_header(kUnknown, kClient, 1, msg::kOk), {buffer_of(t)}), SendStatus::kNotAvailable);
  EXPECT_EQ(router_.send(test::tag_header(kUnknown, kClient, 1, msg::kData), {buffer_of(t)}),
            SendStatus::kNotAvailable);
  const auto c = router_.counters();
  EXPECT_EQ(c.unroutable, 2u);
  EXPECT_EQ(c.not_available, 0u);
  // Nobody got a NOT_AVAILABLE for a reply.
  EXPECT_EQ(client_box_.queued(), 0u);
  EXPECT_EQ(server_box_.queued(), 0u);
}

TEST_F(RouterTest, RequestWhoseSourceIsAlsoUnknownEndsWithoutALoop) {
  const Tag t{1, 0};
  EXPECT_EQ(router_.send(test::tag_header(kUnknown, kOther, 1, msg::kOn), {buffer_of(t)}), SendStatus::kNotAvailable);
  const auto c = router_.counters();
  EXPECT_EQ(c.not_available, 1u);
  EXPECT_EQ(c.unroutable, 1u);  // the NOT_AVAILABLE reply itself had nowhere to go
}

TEST_F(RouterTest, OtherSystemsGoToTheUplink) {
  Mailbox uplink(Address::make(kSys, classes::kExecutor, 0, 7), 4, 512);
  const Address remote = Address::make(3, class_ids::kLadar, 0, 0);
  const Tag t{5, 0};
  // Without an uplink a remote request is answered NOT_AVAILABLE like an unknown one.
  EXPECT_EQ(router_.send(test::tag_header(remote, kClient, 1, msg::kOn), {buffer_of(t)}), SendStatus::kNotAvailable);
  EXPECT_EQ(client_box_.queued(), 1u);
  (void)client_box_.receive(buf_, Mailbox::kNonBlocking);
  router_.set_uplink(&uplink);
  EXPECT_EQ(router_.send(test::tag_header(remote, kClient, 1, msg::kOn), {buffer_of(t)}), SendStatus::kOk);
  EXPECT_EQ(router_.send(test::tag_header(Address::make(kToolSystem, classes::kTool, 1, 1), kClient, 1),
                         {buffer_of(t)}),
            SendStatus::kOk);
  EXPECT_EQ(uplink.queued(), 2u);
  EXPECT_EQ(router_.counters().sent_uplink, 2u);
  // A local unknown address still does not leave the host.
  EXPECT_EQ(router_.send(test::tag_header(kUnknown, kClient, 1, msg::kOn), {buffer_of(t)}), SendStatus::kNotAvailable);
  EXPECT_EQ(uplink.queued(), 2u);
  router_.set_uplink(nullptr);
}

TEST_F(RouterTest, DeliverLocalAnswersOnlyForItsOwnSystem) {
  alignas(8) std::array<std::byte, sizeof(MessageHeader)> raw{};
  MessageHeader h = make_header(kUnknown, kClient, msg::kGetStatus, 1, 4, 0);
  std::memcpy(raw.data(), &h, sizeof h);
  EXPECT_EQ(router_.deliver_local(raw), SendStatus::kNotAvailable);
  EXPECT_EQ(router_.counters().not_available, 1u);
  ASSERT_EQ(client_box_.queued(), 1u);
  // Someone else's system: not ours to answer.
  h = make_header(Address::make(9, class_ids::kLadar, 0), kClient, msg::kGetStatus, 1, 5, 0);
  std::memcpy(raw.data(), &h, sizeof h);
  EXPECT_EQ(router_.deliver_local(raw), SendStatus::kNotAvailable);
  EXPECT_EQ(router_.counters().not_available, 1u);
  EXPECT_EQ(client_box_.queued(), 1u);
}

TEST_F(RouterTest, SharedSystemSendsUnknownOwnAddressesToTheUplinkAndLeavesAnswersToIt) {
  Mailbox uplink(Address::make(kSys, classes::kExecutor, 0, 7), 4, 512);
  Mailbox large(Address::make(kSys, classes::kExecutor, 0, 8), 1, 4096);
  router_.set_uplink(&uplink, &large);
  router_.set_system_shared(true);
  const Tag t{5, 0};
  // Another host of this robot may own it: out it goes, no NOT_AVAILABLE here.
  EXPECT_EQ(router_.send(test::tag_header(kUnknown, kClient, 1, msg::kOn), {buffer_of(t)}), SendStatus::kOk);
  EXPECT_EQ(uplink.queued(), 1u);
  EXPECT_EQ(client_box_.queued(), 0u);
  // Larger than the uplink's slots: the large uplink.
  std::array<std::byte, 1000> big{};
  const MessageHeader h = make_header(kUnknown, kClient, msg::kData, 1, 2, big.size());
  EXPECT_EQ(router_.send(h, {ConstBuffer{big.data(), big.size()}}), SendStatus::kOk);
  EXPECT_EQ(large.queued(), 1u);
  // From the network: not ours to answer either (the transport decides).
  alignas(8) std::array<std::byte, sizeof(MessageHeader)> raw{};
  const MessageHeader req = make_header(kUnknown, kClient, msg::kGetStatus, 1, 4, 0);
  std::memcpy(raw.data(), &req, sizeof req);
  EXPECT_EQ(router_.deliver_local(raw), SendStatus::kNotAvailable);
  EXPECT_EQ(router_.counters().not_available, 0u);
  EXPECT_EQ(client_box_.queued(), 0u);
  router_.set_uplink(nullptr);
  router_.set_system_shared(false);
}

class EndpointTest : public RouterTest {
 protected:
  // Serves one request on the server mailbox with `respond`, from another thread.
  template <typename F>
  std::thread serve_one(F respond) {
    return std::thread([this, respond] {
      alignas(8) std::array<std::byte, 512> b{};
      const auto r = server_box_.receive(b, 10 * rt::kNsPerSec);
      ASSERT_EQ(r.status, RecvStatus::kOk);
      respond(r.header);
    });
  }
  // A call whose request is answered only with `answer(request)`, sent back to the
  // caller: it times out, and the answer is counted as a stale reply (not taken).
  void expect_answer_not_taken_for_the_reply(const std::function<MessageHeader(const MessageHeader&)>& answer) {
    Endpoint client(router_, client_box_, 5);
    auto t = serve_one([&](const MessageHeader& req) {
      EXPECT_EQ(router_.send(answer(req), std::span<const ConstBuffer>{}), SendStatus::kOk);
    });
    const auto r = client.call(kServer, msg::kOn, buf_, 300 * rt::kNsPerMs);
    t.join();
    EXPECT_EQ(r.status, CallStatus::kTimeout);
    EXPECT_EQ(client.stale_replies(), 1u);
  }
};

TEST_F(EndpointTest, CallGetsTheMatchingReplyWithItsBody) {
  Watchdog dog;
  Endpoint client(router_, client_box_, 5);
  Endpoint server(router_, server_box_, 5);
  auto t = serve_one([&](const MessageHeader& req) {
    EXPECT_EQ(req.type, msg::kGetData);
    EXPECT_EQ(req.source(), kClient);
    const Tag body{99, 0};
    const ConstBuffer part = buffer_of(body);
    EXPECT_EQ(server.reply(req, msg::kData, std::span<const ConstBuffer>(&part, 1)), SendStatus::kOk);
  });
  const auto r = client.call(kServer, msg::kGetData, buf_, test::kCallTimeoutNs);
  t.join();
  ASSERT_EQ(r.status, CallStatus::kOk);
  EXPECT_EQ(r.reply.type, msg::kData);
  ASSERT_EQ(r.body.size(), sizeof(Tag));
  Tag got;
  std::memcpy(&got, r.body.data(), sizeof got);
  EXPECT_EQ(got.id, 99u);
  EXPECT_EQ(client.stale_replies(), 0u);
}

TEST_F(EndpointTest, StaleReplyWithAnotherSequenceIsDiscardedAndCounted) {
  Watchdog dog;
  Endpoint client(router_, client_box_, 5);
  Endpoint server(router_, server_box_, 5);
  auto t = serve_one([&](const MessageHeader& req) {
    MessageHeader stale = req;
    stale.seq = static_cast<uint8_t>(req.seq + 1);  // the answer to some other call
    (void)server.reply(stale, msg::kError);
    (void)server.reply(req, msg::kOk);
  });
  const auto r = client.call(kServer, msg::kOn, buf_, test::kCallTimeoutNs);
  t.join();
  ASSERT_EQ(r.status, CallStatus::kOk);
  EXPECT_EQ(r.reply.type, msg::kOk);  // not the stale ERROR queued before it
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(client.stale_replies(), 1u);
}

TEST_F(EndpointTest, RetryAfterALostRequestGetsTheReplyAndALateReplyIsStale) {
  Watchdog dog;
  Endpoint client(router_, client_box_, 5);
  Endpoint server(router_, server_box_, 5);
  // The first request is "lost" (never answered in time); the second is answered, and
  // only then the late answer to the first arrives.
  std::thread t([&] {
    alignas(8) std::array<std::byte, 512> b{};
    const auto first = server_box_.receive(b, 10 * rt::kNsPerSec);
    ASSERT_EQ(first.status, RecvStatus::kOk);
    const auto second = server_box_.receive(b, 10 * rt::kNsPerSec);
    ASSERT_EQ(second.status, RecvStatus::kOk);
    EXPECT_NE(first.header.seq, second.header.seq);
    (void)server.reply(second.header, msg::kOk);
    (void)server.reply(first.header, msg::kError);
  });
  const auto r = client.call_with_retry(kServer, msg::kOn, {}, buf_, RetryPolicy{200 * rt::kNsPerMs, 3});
  t.join();
  ASSERT_EQ(r.status, CallStatus::kOk);
  EXPECT_EQ(r.reply.type, msg::kOk);
  EXPECT_EQ(client.retries(), 1u);
  // The late ERROR to the first attempt is discarded by the next call.
  auto t2 = serve_one([&](const MessageHeader& req) { (void)server.reply(req, msg::kOk); });
  const auto r2 = client.call(kServer, msg::kGetStatus, buf_, test::kCallTimeoutNs);
  t2.join();
  EXPECT_EQ(r2.reply.type, msg::kOk);
  EXPECT_EQ(client.stale_replies(), 1u);
}

TEST_F(EndpointTest, RetriesStopAtTheLastAttemptAndNeverAfterAReply) {
  Watchdog dog;
  Endpoint client(router_, client_box_, 5);
  auto r = client.call_with_retry(kServer, msg::kOn, {}, buf_, RetryPolicy{50 * rt::kNsPerMs, 3});
  EXPECT_EQ(r.status, CallStatus::kTimeout);
  EXPECT_EQ(client.retries(), 2u);
  EXPECT_EQ(server_box_.queued(), 3u);  // three attempts were sent
  // NOT_AVAILABLE is an answer: no retry.
  r = client.call_with_retry(kUnknown, msg::kOn, {}, buf_, RetryPolicy{50 * rt::kNsPerMs, 3});
  EXPECT_EQ(r.status, CallStatus::kOk);
  EXPECT_EQ(r.reply.type, msg::kNotAvailable);
  EXPECT_EQ(client.retries(), 2u);
}

TEST_F(EndpointTest, ReplyFromTheWrongSourceIsNotAccepted) {
  Watchdog dog;
  // Right sequence number, but it comes from another component.
  expect_answer_not_taken_for_the_reply(
      [](const MessageHeader& req) { return make_header(req.source(), kOther, msg::kOk, req.priority, req.seq, 0); });
}

TEST_F(EndpointTest, RequestEchoedBackIsNotTakenForAReply) {
  Watchdog dog;
  // Same source and sequence, but a request type.
  expect_answer_not_taken_for_the_reply(
      [](const MessageHeader& req) { return make_header(req.source(), kServer, msg::kOn, req.priority, req.seq, 0); });
}

TEST_F(EndpointTest, CallTimesOutWhenNobodyServesTheMailbox) {
  Watchdog dog;
  Endpoint client(router_, client_box_, 5);
  const auto r = client.call(kServer, msg::kGetStatus, buf_, 50 * rt::kNsPerMs);
  EXPECT_EQ(r.status, CallStatus::kTimeout);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(server_box_.queued(), 1u);  // the request is there, unanswered
  // A late reply to the timed-out call is stale for the next call.
  alignas(8) std::array<std::byte, 512> b{};
  const auto req = server_box_.receive(b, Mailbox::kNonBlocking);
  ASSERT_EQ(req.status, RecvStatus::kOk);
  Endpoint server(router_, server_box_, 5);
  ASSERT_EQ(server.reply(req.header, msg::kOk), SendStatus::kOk);
  auto t = serve_one([&](const MessageHeader& next) { (void)server.reply(next, msg::kDisabled); });
  const auto r2 = client.call(kServer, msg::kGetStatus, buf_, test::kCallTimeoutNs);
  t.join();
  ASSERT_EQ(r2.status, CallStatus::kOk);
  EXPECT_EQ(r2.reply.type, msg::kDisabled);
  EXPECT_EQ(client.stale_replies(), 1u);
}

TEST_F(EndpointTest, ReplyLargerThanTheBufferIsReportedTooSmall) {
  Watchdog dog;
  Endpoint client(router_, client_box_, 5);
  Endpoint server(router_, server_box_, 5);
  auto t = serve_one([&](const MessageHeader& req) {
    std::array<std::byte, 100> big{};
    const ConstBuffer part{big.data(), big.size()};
    (void)server.reply(req, msg::kData, std::span<const ConstBuffer>(&part, 1));
  });
  alignas(8) std::array<std::byte, 64> small{};
  const auto r = client.call(kServer, msg::kGetData, small, test::kCallTimeoutNs);
  t.join();
  EXPECT_EQ(r.status, CallStatus::kTooSmall);
}

TEST_F(EndpointTest, SendFailsWhenTheDestinationRefuses) {
  Endpoint client(router_, client_box_, 0);
  Mailbox tiny(Address::make(kSys, class_ids::kProbe, 3, 0), 1, 64);
  router_.add(tiny);
  const Tag t{1, 0};
  ASSERT_EQ(tiny.try_send(test::tag_header(tiny.address(), kClient, 200), {buffer_of(t)}), SendStatus::kOk);
  const auto r = client.call(tiny.address(), msg::kOn, buf_, test::kCallTimeoutNs);
  EXPECT_EQ(r.status, CallStatus::kSendFailed);
  EXPECT_EQ(router_.counters().failed, 1u);
  router_.remove(tiny.address());
}

}  // namespace
}  // namespace rack::tims
