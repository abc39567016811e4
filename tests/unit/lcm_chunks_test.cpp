// The TiMS message on the wire without a network: ChunkPublisher cuts messages into
// tims_packet chunks (plain bytes, collected here), ChunkReassembler puts them together
// again (tims/src/lcm_transport_chunks.h). Order, duplicates, compression, a lost
// chunk, a message for another host, the slot limit, and packets that disagree.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "lcm_transport_chunks.h"
#include "lcm_transport_packet.h"
#include "rack/rt/clock.h"
#include "rack/tims/message.h"

namespace rack::tims {
namespace {

using Packet = std::vector<uint8_t>;

constexpr int64_t kSender = 0x1111;
constexpr int64_t kReceiver = 0x2222;
const Address kFrom = Address::make(1, 40, 0);
const Address kTo = Address::make(2, 41, 3);

// A message of `body` bytes: a TiMS header, then a pattern (compressible when `smooth`).
std::vector<std::byte> message(std::size_t body, bool smooth = false) {
  std::vector<std::byte> m(sizeof(MessageHeader) + body);
  const MessageHeader h = make_header(kTo, kFrom, msg::kGetData, 0, 7, body);
  std::memcpy(m.data(), &h, sizeof h);
  for (std::size_t i = 0; i < body; ++i) {
    const auto v = smooth ? (i / 512) : (i * 2654435761u) >> 13;
    m[sizeof h + i] = static_cast<std::byte>(v & 0xFF);
  }
  return m;
}

struct Collect final : PacketOut {
  std::vector<Packet> packets;
  int send_packet(uint8_t* buf, std::size_t len) override {
    packets.emplace_back(buf, buf + len);
    return 0;
  }
};

struct Sink final : MessageSink {
  bool want = true;
  std::vector<std::vector<std::byte>> messages;
  int64_t origin = 0;
  int32_t seq = 0;
  int8_t hops = -1;
  bool wants(const std::byte*, std::size_t) override { return want; }
  void take_message(std::byte* msg, uint32_t len, int64_t o, int32_t s, int8_t h) override {
    messages.emplace_back(msg, msg + len);
    origin = o;
    seq = s;
    hops = h;
  }
};

class LcmChunksTest : public ::testing::Test {
 protected:
  // Publishes `m` on a network with `compression`; the packets it made.
  std::vector<Packet> publish(const std::vector<std::byte>& m, Compression compression = Compression::kNone,
                              int32_t seq = 5) {
    NetworkConfig c;
    c.compression = compression;
    ChunkPublisher publisher(c, limits.max_message_bytes, 0, send_log);
    Collect out;
    EXPECT_TRUE(publisher.publish(m.data(), static_cast<uint32_t>(m.size()), kSender, 0, 2, seq, false, out));
    return out.packets;
  }
  // The receiving side, made at first use (with the limits as the test set them).
  ChunkReassembler& reassembler() {
    if (!receiver) receiver = std::make_unique<ChunkReassembler>(kReceiver, limits, receive_log, sink);
    return *receiver;
  }
  void feed(const Packet& p) { reassembler().on_packet(p.data(), p.size(), "TIMS"); }

  ChunkLimits limits{256 * 1024, 2, 1'000'000'000};
  TransportStats stats;
  std::string warnings;
  Sink sink;
  lcm_rx::RateLimitedWarn warn{[this](const std::string& s) { warnings += s + "\n"; }};
  NetworkLog send_log{stats, warn, "out", "memq://"};
  NetworkLog receive_log{stats, warn, "in", "memq://"};
  std::unique_ptr<ChunkReassembler> receiver;
};

TEST_F(LcmChunksTest, AMessageInChunksArrivesWholeInAnyOrderAndDuplicatesAreIgnored) {
  const auto m = message(200'000);
  auto packets = publish(m);
  ASSERT_EQ(packets.size(), 4u) << "200 KB in chunks of 60000 bytes";
  EXPECT_EQ(packets[0].size(), lcm_detail::kPacketPrefix + lcm_detail::kChunk);
  std::reverse(packets.begin(), packets.end());
  feed(packets[0]);
  feed(packets[0]);  // a duplicate
  for (std::size_t i = 1; i < packets.size(); ++i) feed(packets[i]);
  ASSERT_EQ(sink.messages.size(), 1u) << warnings;
  EXPECT_TRUE(sink.messages[0] == m);
  EXPECT_EQ(sink.origin, kSender);
  EXPECT_EQ(sink.seq, 5);
  EXPECT_EQ(sink.hops, 2);
  const TransportCounters c = stats.snapshot();
  EXPECT_EQ(c.packets_out, 4u);
  EXPECT_EQ(c.messages_out, 1u);
  EXPECT_EQ(c.packets_in, 5u);
  EXPECT_EQ(c.malformed, 0u);
  EXPECT_EQ(c.lost_messages, 0u);
}

TEST_F(LcmChunksTest, ACompressedMessageIsSmallerOnTheWireAndDecompressedOnReceipt) {
  const auto m = message(200'000, true);
  const auto packets = publish(m, Compression::kZstd);
  ASSERT_LT(packets.size(), 4u);
  EXPECT_EQ(packets[0][lcm_detail::kOffEncoding], 2) << "header as it is, the body one zstd frame";
  for (const auto& p : packets) feed(p);
  ASSERT_EQ(sink.messages.size(), 1u) << warnings;
  EXPECT_TRUE(sink.messages[0] == m);
  const TransportCounters c = stats.snapshot();
  EXPECT_EQ(c.compressed_out, 1u);
  EXPECT_EQ(c.bytes_out, m.size());
  EXPECT_LT(c.wire_bytes_out, m.size() / 10);
}

TEST_F(LcmChunksTest, AMessageMissingAChunkIsReportedLostWhenItTimesOut) {
  const auto packets = publish(message(200'000));
  for (std::size_t i = 0; i < packets.size(); ++i) {
    if (i != 2) feed(packets[i]);
  }
  EXPECT_TRUE(sink.messages.empty());
  reassembler().expire(rt::monotonic_ns());  // not yet
  EXPECT_EQ(stats.snapshot().lost_messages, 0u);
  reassembler().expire(rt::monotonic_ns() + limits.timeout_ns + 1);
  EXPECT_EQ(stats.snapshot().lost_messages, 1u);
  EXPECT_NE(warnings.find("message from " + kFrom.str() + " to " + kTo.str() + " (200016 bytes) lost on network 'in'"),
            std::string::npos)
      << warnings;
  EXPECT_NE(warnings.find("1 of 4 chunks missing (timed out)"), std::string::npos) << warnings;
  feed(packets[2]);  // too late: a first chunk of nothing, waiting again
  EXPECT_TRUE(sink.messages.empty());
}

TEST_F(LcmChunksTest, AMessageForAnotherHostIsDroppedFromItsFirstChunkOn) {
  sink.want = false;
  const auto packets = publish(message(200'000));
  for (const auto& p : packets) feed(p);
  EXPECT_TRUE(sink.messages.empty());
  reassembler().expire(rt::monotonic_ns() + limits.timeout_ns + 1);
  const TransportCounters c = stats.snapshot();
  EXPECT_EQ(c.not_for_us, 1u);
  EXPECT_EQ(c.lost_messages, 0u) << "its other chunks were never reassembled";
}

TEST_F(LcmChunksTest, WhenEverySlotIsBusyTheOldestMessageGivesWay) {
  const auto a = publish(message(200'000), Compression::kNone, 1);
  const auto b = publish(message(200'000), Compression::kNone, 2);
  const auto c = publish(message(200'000), Compression::kNone, 3);
  feed(a[0]);
  feed(b[0]);
  feed(c[0]);  // two slots: a gives way
  EXPECT_EQ(stats.snapshot().lost_messages, 1u);
  EXPECT_NE(warnings.find("displaced by newer messages"), std::string::npos) << warnings;
  for (std::size_t i = 1; i < c.size(); ++i) feed(c[i]);
  for (std::size_t i = 1; i < b.size(); ++i) feed(b[i]);
  ASSERT_EQ(sink.messages.size(), 2u);
  EXPECT_EQ(sink.seq, 2);
}

TEST_F(LcmChunksTest, PacketsOutsideTheLimitsOrDisagreeingWithTheirMessageAreRefusedWithTheReason) {
  limits.max_message_bytes = 128 * 1024;
  ChunkLimits big = limits;
  big.max_message_bytes = 1024 * 1024;
  NetworkConfig nc;
  ChunkPublisher large(nc, big.max_message_bytes, 0, send_log);
  Collect out;
  const auto m = message(200'000);
  ASSERT_TRUE(large.publish(m.data(), static_cast<uint32_t>(m.size()), kSender, 0, 0, 9, false, out));
  feed(out.packets[0]);
  EXPECT_NE(warnings.find("bad chunk fields (total 200016"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("limit 131072 bytes"), std::string::npos) << warnings;

  // The last chunk first (it opens a slot), then a first chunk of the same message
  // that gives another size.
  auto packets = publish(message(100'000), Compression::kNone, 4);
  ASSERT_EQ(packets.size(), 2u);
  feed(packets[1]);
  lcm_detail::put_be(packets[0].data() + lcm_detail::kOffTotal, 120'000, 4);
  lcm_detail::put_be(packets[0].data() + lcm_detail::kOffEncoded, 120'000, 4);
  feed(packets[0]);
  EXPECT_NE(warnings.find("a chunk disagrees with its message's first chunk"), std::string::npos) << warnings;

  Packet short_one(20, 0);
  feed(short_one);
  const TransportCounters c = stats.snapshot();
  EXPECT_EQ(c.malformed_packet, 3u);
  EXPECT_EQ(c.malformed, 3u);
  EXPECT_TRUE(sink.messages.empty());
}

TEST_F(LcmChunksTest, OurOwnPacketsEchoedByMulticastAreDropped) {
  NetworkConfig nc;
  ChunkPublisher own(nc, limits.max_message_bytes, 0, send_log);
  Collect out;
  const auto m = message(100);
  ASSERT_TRUE(own.publish(m.data(), static_cast<uint32_t>(m.size()), kReceiver, 0, 0, 1, false, out));
  feed(out.packets[0]);
  EXPECT_TRUE(sink.messages.empty());
  EXPECT_EQ(stats.snapshot().malformed, 0u);
  const auto other = publish(m);
  feed(other[0]);
  ASSERT_EQ(sink.messages.size(), 1u) << "a one-chunk message of another host";
  EXPECT_TRUE(sink.messages[0] == m);
}

}  // namespace
}  // namespace rack::tims
