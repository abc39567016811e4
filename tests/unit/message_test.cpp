// TiMS header encoding in both byte orders, body conversion by field table, and
// address formatting/parsing.
#include "rack/components/class_ids.h"
#include "rack/tims/message.h"

#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstring>
#include <string>
#include <vector>

#include "rack/core/data_component.h"
#include "rack/core/wire.h"
#include "probe/probe_types.h"
#include "rack/interfaces/demo.h"
#include "rack/tims/address.h"
#include "rack/tims/payload.h"

namespace rack::tims {
namespace {

// Writes `v` big-endian at `out` (independent of the code under test).
template <typename U>
void put_be(std::byte* out, U v) {
  for (std::size_t i = 0; i < sizeof(U); ++i) {
    out[i] = static_cast<std::byte>((v >> (8 * (sizeof(U) - 1 - i))) & 0xFF);
  }
}
template <typename U>
void put_le(std::byte* out, U v) {
  for (std::size_t i = 0; i < sizeof(U); ++i) out[i] = static_cast<std::byte>((v >> (8 * i)) & 0xFF);
}

class MessageHeaderTest : public ::testing::Test {
 protected:
  static constexpr Address kDest = Address::make(3, class_ids::kGenerator, 7, 2);
  static constexpr Address kSrc = Address::make(255, classes::kTool, 9, 1);

  // A 16-byte header followed by `body_len` zero bytes, header in the given order.
  static std::vector<std::byte> encoded(const MessageHeader& h, bool little_endian) {
    std::vector<std::byte> bytes(h.length);
    encode_header(h, little_endian, bytes.data());
    return bytes;
  }
  static void expect_same(const MessageHeader& a, const MessageHeader& b) {
    EXPECT_EQ(a.type, b.type);
    EXPECT_EQ(a.priority, b.priority);
    EXPECT_EQ(a.seq, b.seq);
    EXPECT_EQ(a.dest, b.dest);
    EXPECT_EQ(a.src, b.src);
    EXPECT_EQ(a.length, b.length);
  }
};

TEST_F(MessageHeaderTest, RoundTripsLittleEndian) {
  const MessageHeader h = make_header(kDest, kSrc, msg::kGetData, 42, 200, 8);
  const auto bytes = encoded(h, true);
  // Wire layout: flags, type, priority, seq, then dest/src/length little-endian.
  EXPECT_EQ(bytes[0] & std::byte{kFlagHeaderLittleEndian}, std::byte{kFlagHeaderLittleEndian});
  EXPECT_EQ(static_cast<int8_t>(bytes[1]), msg::kGetData);
  EXPECT_EQ(bytes[2], std::byte{42});
  EXPECT_EQ(bytes[3], std::byte{200});
  std::array<std::byte, 4> dest_le{};
  put_le(dest_le.data(), kDest.raw());
  EXPECT_EQ(0, std::memcmp(bytes.data() + 4, dest_le.data(), 4));
  MessageHeader out;
  ASSERT_EQ(decode_header(bytes, out), MessageError::kOk);
  expect_same(out, h);
  EXPECT_EQ(out.destination(), kDest);
  EXPECT_EQ(out.source(), kSrc);
  EXPECT_EQ(out.body_length(), 8u);
  EXPECT_TRUE(out.is_request());
}

TEST_F(MessageHeaderTest, RoundTripsBigEndianAndNormalisesFlags) {
  MessageHeader h = make_header(kDest, kSrc, msg::kContData, 7, 3, 24);
  const auto bytes = encoded(h, false);
  EXPECT_EQ(bytes[0] & std::byte{kFlagHeaderLittleEndian}, std::byte{0});
  std::array<std::byte, 16> expect{};
  put_be(expect.data() + 4, kDest.raw());
  put_be(expect.data() + 8, kSrc.raw());
  put_be(expect.data() + 12, uint32_t{16 + 24});
  EXPECT_EQ(0, std::memcmp(bytes.data() + 4, expect.data() + 4, 12)) << "big-endian words on the wire";
  MessageHeader out;
  ASSERT_EQ(decode_header(bytes, out), MessageError::kOk);
  expect_same(out, h);
  EXPECT_FALSE(out.is_request());
  // The header is now in host order and its flag says so; the body flag is kept.
  EXPECT_EQ((out.flags & kFlagHeaderLittleEndian) != 0, kHostLittleEndian);
  EXPECT_EQ(out.flags & kFlagBodyLittleEndian, h.flags & kFlagBodyLittleEndian);
  EXPECT_TRUE(body_is_native(out));
}

TEST_F(MessageHeaderTest, KeepsAForeignBodyFlag) {
  MessageHeader h = make_header(kDest, kSrc, msg::kData, 1, 1, 0);
  h.flags = static_cast<uint8_t>(h.flags ^ kFlagBodyLittleEndian);  // body of the other order
  for (const bool le : {true, false}) {
    const auto bytes = encoded(h, le);
    MessageHeader out;
    ASSERT_EQ(decode_header(bytes, out), MessageError::kOk);
    EXPECT_FALSE(body_is_native(out)) << "header little-endian: " << le;
    EXPECT_EQ((out.flags & kFlagHeaderLittleEndian) != 0, kHostLittleEndian);
  }
}

TEST_F(MessageHeaderTest, RejectsTruncatedHeader) {
  const MessageHeader h = make_header(kDest, kSrc, msg::kOn, 0, 0, 0);
  const auto bytes = encoded(h, true);
  MessageHeader out;
  EXPECT_EQ(decode_header(std::span<const std::byte>(bytes).first(15), out), MessageError::kTruncatedHeader);
  EXPECT_EQ(decode_header(std::span<const std::byte>(), out), MessageError::kTruncatedHeader);
}

TEST_F(MessageHeaderTest, RejectsLengthMismatchInBothByteOrders) {
  const MessageHeader h = make_header(kDest, kSrc, msg::kData, 0, 0, 10);
  for (const bool le : {true, false}) {
    std::vector<std::byte> bytes = encoded(h, le);
    MessageHeader out;
    EXPECT_EQ(decode_header(bytes, out), MessageError::kOk) << "le " << le;
    bytes.push_back(std::byte{0});  // one byte more than the header says
    EXPECT_EQ(decode_header(bytes, out), MessageError::kLengthMismatch) << "le " << le;
    bytes.resize(20);  // fewer
    EXPECT_EQ(decode_header(bytes, out), MessageError::kLengthMismatch) << "le " << le;
  }
}

TEST_F(MessageHeaderTest, RejectsUnknownFlags) {
  const MessageHeader h = make_header(kDest, kSrc, msg::kOn, 0, 0, 0);
  for (const uint8_t bad : {uint8_t{0x04}, uint8_t{0x80}}) {
    auto bytes = encoded(h, true);
    ASSERT_FALSE(bytes.empty());
    bytes.front() = static_cast<std::byte>(std::to_integer<uint8_t>(bytes.front()) | bad);
    MessageHeader out;
    EXPECT_EQ(decode_header(bytes, out), MessageError::kUnknownFlags);
  }
  EXPECT_NE(describe(MessageError::kUnknownFlags), nullptr);
}

TEST_F(MessageHeaderTest, ReplyHeaderSwapsAddressesAndKeepsSequence) {
  const MessageHeader req = make_header(kDest, kSrc, msg::kGetStatus, 9, 77, 0);
  const MessageHeader rep = make_reply_header(req, msg::kEnabled, 4);
  EXPECT_EQ(rep.destination(), kSrc);
  EXPECT_EQ(rep.source(), kDest);
  EXPECT_EQ(rep.seq, 77);
  EXPECT_EQ(rep.priority, 9);
  EXPECT_EQ(rep.length, 20u);
  EXPECT_STREQ(msg::name(msg::kNotAvailable), "NOT_AVAILABLE");
  EXPECT_EQ(msg::name(99), nullptr);
}

class PayloadByteOrderTest : public ::testing::Test {};

TEST_F(PayloadByteOrderTest, BigEndianGeneratorDataConvertsBack) {
  interfaces::GeneratorData want;
  want.value = -1234.5625;
  want.counter = -42;
  // The body as a big-endian peer sends it, written by hand.
  std::array<std::byte, sizeof(interfaces::GeneratorData)> body{};
  put_be(body.data() + offsetof(interfaces::GeneratorData, value), std::bit_cast<uint64_t>(want.value));
  put_be(body.data() + offsetof(interfaces::GeneratorData, counter), static_cast<uint64_t>(want.counter));

  // The header says "body big-endian"; on a little-endian host that is not native.
  MessageHeader h = make_header(Address::make(0, classes::kTool, 1), Address::make(0, class_ids::kGenerator, 1),
                                msg::kData, 0, 0, body.size());
  h.flags = kFlagHeaderLittleEndian;  // header LE, body BE
  const bool native = body_is_native(h);
  EXPECT_EQ(native, !kHostLittleEndian);

  interfaces::GeneratorData got;
  ASSERT_TRUE(wire::read_payload(body, native, got));
  EXPECT_EQ(got.value, want.value);
  EXPECT_EQ(got.counter, want.counter);

  // Wrong size is refused.
  EXPECT_FALSE(wire::read_payload(std::span<const std::byte>(body).first(15), native, got));
}

TEST_F(PayloadByteOrderTest, SwapFieldsConvertsEveryFieldOfContDataRequest) {
  std::array<std::byte, sizeof(wire::ContDataRequest)> body{};
  put_be(body.data() + offsetof(wire::ContDataRequest, period_ns), uint64_t{50'000'000});
  put_be(body.data() + offsetof(wire::ContDataRequest, mailbox), uint32_t{0x00420101});
  swap_fields(fields_of<wire::ContDataRequest>, body.data(), body.size());
  wire::ContDataRequest got;
  std::memcpy(&got, body.data(), sizeof got);
  if (kHostLittleEndian) {
    EXPECT_EQ(got.period_ns, 50'000'000);
    EXPECT_EQ(got.mailbox, 0x00420101u);
  }
  // Swapping twice is the identity.
  swap_fields(fields_of<wire::ContDataRequest>, body.data(), body.size());
  swap_fields(fields_of<wire::ContDataRequest>, body.data(), body.size());
  wire::ContDataRequest again;
  std::memcpy(&again, body.data(), sizeof again);
  EXPECT_EQ(again.period_ns, got.period_ns);
  EXPECT_EQ(again.mailbox, got.mailbox);
}

TEST_F(PayloadByteOrderTest, SwapFieldsLeavesBytesAndStringsAlone) {
  wire::ParamRecord r;
  wire::copy_text(r.name, "abcdefgh");
  r.kind = 3;
  r.int_value = 0x0102030405060708;
  std::array<std::byte, sizeof r> body{};
  std::memcpy(body.data(), &r, sizeof r);
  swap_fields(fields_of<wire::ParamRecord>, body.data(), body.size());
  wire::ParamRecord got;
  std::memcpy(&got, body.data(), sizeof got);
  EXPECT_STREQ(got.name, "abcdefgh");
  EXPECT_EQ(got.kind, 3);
  EXPECT_EQ(got.int_value, 0x0807060504030201);
}

TEST_F(PayloadByteOrderTest, SwapFieldsSkipsFieldsPastTheGivenSize) {
  std::array<std::byte, sizeof(interfaces::GeneratorData)> body{};
  put_le(body.data() + 8, uint64_t{0x1122334455667788});
  swap_fields(fields_of<interfaces::GeneratorData>, body.data(), 8);  // only `value` fits
  uint64_t counter = 0;
  std::memcpy(&counter, body.data() + 8, 8);
  if (kHostLittleEndian) {
    EXPECT_EQ(counter, 0x1122334455667788u);
  }
}

TEST_F(PayloadByteOrderTest, ReadSampleConvertsAForeignDataMessage) {
  // A DATA body (SampleHeader + ProbeData) from a big-endian peer.
  constexpr std::size_t kSize = sizeof(wire::SampleHeader) + sizeof(interfaces::ProbeData);
  std::array<std::byte, kSize> body{};
  put_be(body.data() + 0, uint64_t{1'700'000'000'123'456'789});
  put_be(body.data() + 8, uint64_t{99});
  put_be(body.data() + 16, uint64_t{5});
  put_be(body.data() + 24, uint64_t{2});
  put_be(body.data() + 32, uint64_t{1});
  MessageHeader h = make_header(Address::make(0, classes::kTool, 1), Address::make(0, class_ids::kProbe, 1), msg::kData,
                                0, 0, kSize);
  h.flags = kHostLittleEndian ? kFlagHeaderLittleEndian : kFlagBodyLittleEndian;  // body foreign
  wire::SampleHeader sh;
  interfaces::ProbeData d;
  ASSERT_TRUE(read_sample(h, body, sh, d));
  if (kHostLittleEndian) {
    EXPECT_EQ(sh.time_ns, 1'700'000'000'123'456'789);
    EXPECT_EQ(sh.sequence, 99u);
    EXPECT_EQ(d.loops, 5);
    EXPECT_EQ(d.on_calls, 2);
    EXPECT_EQ(d.off_calls, 1);
  }
  EXPECT_FALSE(read_sample(h, std::span<const std::byte>(body).first(kSize - 1), sh, d));
}

class AddressTest : public ::testing::Test {};  // class names: builtin_class_names.cpp

TEST_F(AddressTest, FormatsKnownAndUnknownClasses) {
  EXPECT_EQ(Address::make(0, class_ids::kGenerator, 1).str(), "Generator(0/1)");
  EXPECT_EQ(Address::make(0, class_ids::kGenerator, 1, 3).str(), "Generator(0/1)#3");
  EXPECT_EQ(Address::make(0, 0x99, 1).str(), "Class0x99(0/1)");
  EXPECT_EQ(Address::make(254, class_ids::kScan2d, 255, 255).str(), "Scan2D(254/255)#255");
  char small[8];
  Address::make(0, class_ids::kGenerator, 1).format(small, sizeof small);
  EXPECT_STREQ(small, "Generat");  // cut, still terminated
}

TEST_F(AddressTest, FieldsAndComponentAddress) {
  const Address a = Address::make(5, class_ids::kLadar, 7, 3);
  EXPECT_EQ(a.system(), 5);
  EXPECT_EQ(a.class_id(), class_ids::kLadar);
  EXPECT_EQ(a.instance(), 7);
  EXPECT_EQ(a.mailbox(), 3);
  EXPECT_EQ(a.component(), Address::make(5, class_ids::kLadar, 7, 0));
  EXPECT_EQ(a.with_mailbox(9), Address::make(5, class_ids::kLadar, 7, 9));
}

TEST_F(AddressTest, ParseRoundTripsFormattedAddresses) {
  const Address samples[] = {
      Address::make(0, class_ids::kGenerator, 1),
      Address::make(0, class_ids::kGenerator, 1, 3),
      Address::make(0, 0x99, 1),
      Address::make(254, class_ids::kMonitor, 255, 255),
      Address::make(255, classes::kTool, 0, 1),
      Address::make(0, 0, 0),
  };
  for (const Address a : samples) {
    const auto parsed = parse_address(a.str());
    ASSERT_TRUE(parsed.has_value()) << a.str();
    EXPECT_EQ(*parsed, a) << a.str();
  }
  EXPECT_EQ(parse_address("66(0/1)"), Address::make(0, class_ids::kProbe, 1));
  EXPECT_EQ(parse_address("Class0x42(2/3)#4"), Address::make(2, class_ids::kProbe, 3, 4));
}

TEST_F(AddressTest, ParseRejectsMalformedText) {
  for (const char* bad : {"",
                          "Generator",
                          "Generator(",
                          "Generator(0/1",
                          "Generator)0/1(",
                          "(0/1)",
                          "Generator(0-1)",
                          "Generator(/1)",
                          "Generator(0/)",
                          "Generator(0/256)",
                          "Generator(256/0)",
                          "Generator(-1/0)",
                          "Generator(0/1/2)",
                          "Generator(0/1)#",
                          "Generator(0/1)#x",
                          "Generator(0/1)#256",
                          "Generator(0/1)x",
                          "Generator(0/1)(2/3)",
                          "NoSuchClass(0/1)",
                          "Class0xZZ(0/1)",
                          "Class0x100(0/1)",
                          "300(0/1)",
                          " Generator(0/1)",
                          "Generator(0x1/1)"}) {
    EXPECT_FALSE(parse_address(bad).has_value()) << "accepted '" << bad << "'";
  }
}

TEST_F(AddressTest, ClassTableLooksUpBothWays) {
  EXPECT_STREQ(class_name(class_ids::kProbe), "Probe");
  EXPECT_EQ(class_id("Monitor"), class_ids::kMonitor);
  EXPECT_EQ(class_name(0x99), nullptr);
  EXPECT_FALSE(class_id("Nope").has_value());
  EXPECT_FALSE(register_class_name(0x10, "Mine"));  // Chassis: declared by ChassisSim and others
  EXPECT_TRUE(register_class_name(0xA7, "UnitTestClass"));
  EXPECT_TRUE(register_class_name(0xA7, "UnitTestClass"));   // idempotent
  EXPECT_FALSE(register_class_name(0xA8, "UnitTestClass"));  // name taken
  EXPECT_EQ(Address::make(1, 0xA7, 2).str(), "UnitTestClass(1/2)");
  EXPECT_EQ(parse_address("UnitTestClass(1/2)"), Address::make(1, 0xA7, 2));
}

}  // namespace
}  // namespace rack::tims
