// The network boundary without a network: the total decoders of the lcm-gen types
// (tims/src/lcm_wire.h) against lcm-gen's own encoder, and the TiMS transport's and the
// GDOS subscriber's datagram paths driven by handle_datagram() (no socket: they publish
// into an LCM log written to /dev/null). Each refusal is checked for its counter and
// its reason; discover answers for their rate limit.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "gdos_view.h"
#include "lcm_wire.h"
#include "rack/components/class_ids.h"
#include "rack/tims/gdos_lcm.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/router.h"
#include "rack_lcm/tims_packet.hpp"

namespace rack::tims {
namespace {

using Bytes = std::vector<uint8_t>;
constexpr const char* kNoNetwork = "file:///dev/null?mode=w";

template <typename T>
Bytes encode(const T& m) {
  Bytes b(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}
void set32(Bytes& b, std::size_t at, int32_t v) {
  for (int i = 0; i < 4; ++i)
    b[at + static_cast<std::size_t>(i)] = static_cast<uint8_t>(static_cast<uint32_t>(v) >> (24 - 8 * i));
}
Bytes datagram(const std::string& channel, const Bytes& payload) {
  // Built as a string (GCC 12 warns falsely, -Warray-bounds and -Wnull-dereference, on
  // the vector versions of this).
  std::string s("LC02\0\0\0\1", 8);
  s += channel;
  s.push_back('\0');
  s.append(payload.begin(), payload.end());
  return Bytes(s.begin(), s.end());
}

rack_lcm::discover_request a_discover(int64_t origin) {
  rack_lcm::discover_request q;
  q.origin = origin;
  q.relay = 0;
  q.hops = 0;
  q.time_ns = 1;
  q.requester = "pid 1";
  return q;
}
// Offset of `requester`'s length field: fingerprint, origin, relay, hops, time_ns.
constexpr std::size_t kRequesterAt = 8 + 8 + 8 + 1 + 8;

rack_lcm::host_announce an_announce() {
  rack_lcm::host_announce a;
  a.count = 1;
  a.origin = 0x1234;
  a.relay = 0;
  a.hops = 0;
  a.role = 0;
  a.time_ns = 1;
  a.period_ns = 1'000'000'000;
  a.host = "other";
  a.system = 0;
  a.host_id = 3;
  a.pid = 42;
  a.executor = 0x00010300;
  a.components.resize(1);
  a.components[0].address = 0x40010000;
  a.components[0].name = "gen";
  a.components[0].impl = "Generator";
  return a;
}
// Offset of `host`'s length field: fingerprint, count, origin, relay, hops, role, time, period.
constexpr std::size_t kHostAt = 8 + 4 + 8 + 8 + 1 + 1 + 8 + 8;

TEST(LcmWireTest, WhatLcmGenEncodesDecodesTheSame) {
  const auto a = an_announce();
  const Bytes b = encode(a);
  rack_lcm::host_announce out;
  std::string why;
  ASSERT_EQ(wire_lcm::decode(b.data(), b.size(), out, why), static_cast<int>(b.size())) << why;
  EXPECT_EQ(out.host, "other");
  ASSERT_EQ(out.components.size(), 1u);
  EXPECT_EQ(out.components[0].impl, "Generator");
  EXPECT_EQ(encode(out), b);
}

TEST(LcmWireTest, StringLengthsOfZeroNegativeOrBeyondTheBufferAreRefusedWithWhereAndWhy) {
  for (const int32_t len : {0, -1, INT32_MIN, 1000}) {
    Bytes b = encode(a_discover(7));
    set32(b, kRequesterAt, len);
    rack_lcm::discover_request q;
    std::string why;
    EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), q, why), -1) << len;
    EXPECT_NE(why.find("requester at byte 33"), std::string::npos) << why;
    EXPECT_NE(why.find("string length " + std::to_string(len)), std::string::npos) << why;
  }
  Bytes b = encode(an_announce());
  set32(b, kHostAt, 0);
  rack_lcm::host_announce a;
  std::string why;
  EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), a, why), -1);
  EXPECT_EQ(why, "host at byte 46: string length 0 (at least 1: the NUL)");
}

TEST(LcmWireTest, StringsMustEndWithTheirOnlyNul) {
  Bytes b = encode(a_discover(7));
  b[kRequesterAt + 4 + 1] = 0;  // "p\0d 1\0"
  rack_lcm::discover_request q;
  std::string why;
  EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), q, why), -1);
  EXPECT_NE(why.find("NUL before its end"), std::string::npos) << why;
  b = encode(a_discover(7));
  b.back() = 'x';
  EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), q, why), -1);
  EXPECT_NE(why.find("not NUL-terminated"), std::string::npos) << why;
}

TEST(LcmWireTest, CountsAreBoundedByTheBytesLeftBeforeAllocating) {
  for (const int32_t count : {-1, 2, 0x7fffffff}) {
    Bytes b = encode(an_announce());
    set32(b, 8, count);
    rack_lcm::host_announce a;
    std::string why;
    EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), a, why), -1) << count;
    EXPECT_NE(why.find("components at byte"), std::string::npos) << why;
    EXPECT_TRUE(a.components.empty());
  }
  rack_lcm::gdos_batch g;
  g.time_ns = 0;
  g.host = "h";
  g.pid = 1;
  g.count = 0;
  Bytes b = encode(g);
  set32(b, b.size() - 4, 1 << 30);
  std::string why;
  EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), g, why), -1);
  EXPECT_NE(why.find("count 1073741824"), std::string::npos) << why;
}

TEST(LcmWireTest, TruncatedAndForeignPayloadsAreRefused) {
  const Bytes b = encode(an_announce());
  rack_lcm::host_announce a;
  std::string why;
  for (std::size_t n = 0; n < b.size(); ++n) {
    EXPECT_EQ(wire_lcm::decode(b.data(), n, a, why), -1) << n;
  }
  rack_lcm::gdos_listener l;
  EXPECT_EQ(wire_lcm::decode(b.data(), b.size(), l, why), -1);
  EXPECT_NE(why.find("fingerprint"), std::string::npos) << why;
}

TEST(LcmWireTest, DatagramFraming) {
  const Bytes d = datagram("TIMS", {1, 2, 3});
  auto g = wire_lcm::parse_datagram(d.data(), d.size());
  ASSERT_EQ(g.kind, wire_lcm::LcmDatagram::kMessage);
  EXPECT_EQ(g.channel, "TIMS");
  EXPECT_EQ(g.payload_size, 3u);
  const Bytes frag = {'L', 'C', '0', '3', 0, 0, 0, 1, 0, 1, 0, 0};
  EXPECT_EQ(wire_lcm::parse_datagram(frag.data(), frag.size()).kind, wire_lcm::LcmDatagram::kFragment);
  const Bytes unterminated = {'L', 'C', '0', '2', 0, 0, 0, 1, 'T', 'I'};
  EXPECT_EQ(wire_lcm::parse_datagram(unterminated.data(), unterminated.size()).kind, wire_lcm::LcmDatagram::kInvalid);
  const Bytes long_name = datagram(std::string(64, 'c'), {});
  g = wire_lcm::parse_datagram(long_name.data(), long_name.size());
  EXPECT_EQ(g.kind, wire_lcm::LcmDatagram::kInvalid);
  EXPECT_STREQ(g.why, "LCM channel name longer than 63 bytes");
  EXPECT_EQ(wire_lcm::parse_datagram(d.data(), 7).kind, wire_lcm::LcmDatagram::kInvalid);
}

class TransportDatagramTest : public ::testing::Test {
 protected:
  TransportDatagramTest() {
    LcmTransportConfig c;
    c.url = kNoNetwork;
    c.discover_answer_interval_ns = 60'000'000'000;  // one answer in this test
    c.warn = [this](const std::string& s) { warnings += s + "\n"; };
    transport = std::make_unique<LcmTransport>(router, c);
    HostInfo self;
    self.host = "unit";
    self.executor = Address::make(0, classes::kExecutor, 0);
    transport->set_announcement(self);
  }
  void feed(const Bytes& d) { transport->handle_datagram(d.data(), d.size()); }

  Router router{0};
  std::string warnings;
  std::unique_ptr<LcmTransport> transport;
};

TEST_F(TransportDatagramTest, EachRefusalIsCountedByKindWithItsReason) {
  Bytes bad_discover = encode(a_discover(9));
  set32(bad_discover, kRequesterAt, 0);
  feed(datagram("TIMS_DISCOVER", bad_discover));
  Bytes bad_announce = encode(an_announce());
  set32(bad_announce, kHostAt, -5);
  feed(datagram("TIMS_ANNOUNCE", bad_announce));
  feed({'L', 'C', '0', '3', 0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2});
  feed({'L', 'C'});
  feed(datagram("TIMS", Bytes(12, 0)));
  const TransportCounters c = transport->counters();
  EXPECT_EQ(c.malformed_discover, 1u);
  EXPECT_EQ(c.malformed_announce, 1u);
  EXPECT_EQ(c.lcm_fragments, 1u);
  EXPECT_EQ(c.malformed_lcm, 1u);
  EXPECT_EQ(c.malformed_packet, 1u);
  EXPECT_EQ(c.malformed, 4u) << "fragments are refused, not malformed";
  EXPECT_NE(warnings.find("requester at byte 33: string length 0"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("host at byte 46: string length -5"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("refused an LCM fragment"), std::string::npos) << warnings;
  EXPECT_TRUE(transport->hosts().empty());
}

TEST_F(TransportDatagramTest, DiscoverRequestsShareOneAnswerPerInterval) {
  for (int i = 0; i < 50; ++i) feed(datagram("TIMS_DISCOVER", encode(a_discover(100 + i))));
  const TransportCounters c = transport->counters();
  // The first at once, the second when the interval has passed (it came after the
  // first answer, so that answer did not serve it), the other 48 share the second.
  EXPECT_EQ(c.discovers_answered, 2u);
  EXPECT_EQ(c.discovers_suppressed, 48u);
  EXPECT_EQ(c.malformed, 0u);
}

TEST_F(TransportDatagramTest, AnnouncementsWithControlCharactersInNamesAreRefused) {
  auto a = an_announce();
  a.components[0].name = "gen\x1b[2J";
  feed(datagram("TIMS_ANNOUNCE", encode(a)));
  EXPECT_TRUE(transport->hosts().empty());
  EXPECT_EQ(transport->counters().malformed_announce, 1u);
  EXPECT_NE(warnings.find("control character"), std::string::npos) << warnings;
}

TEST_F(TransportDatagramTest, AValidAnnouncementFillsTheTable) {
  feed(datagram("TIMS_ANNOUNCE", encode(an_announce())));
  const auto hosts = transport->hosts();
  ASSERT_EQ(hosts.size(), 1u) << warnings;
  EXPECT_EQ(hosts[0].host, "other");
  ASSERT_EQ(hosts[0].components.size(), 1u);
  EXPECT_EQ(hosts[0].components[0].name, "gen");
}

TEST(GdosDatagramTest, BadBatchesAndFragmentsAreCountedAndGoodRecordsPass) {
  GdosSubscriber sub(kNoNetwork, kGdosChannel, false, "unit");
  std::vector<GdosRecord> seen;
  const auto sink = [&](const GdosRecord& r) { seen.push_back(r); };
  rack_lcm::gdos_batch g;
  g.time_ns = 0;
  g.host = "h";
  g.pid = 1;
  g.count = 1;
  g.records.resize(1);
  g.records[0].time_ns = 1;
  g.records[0].sequence = 1;
  g.records[0].source = 0x40000000;
  g.records[0].name = "generator";
  g.records[0].level = 3;
  g.records[0].dropped_before = 0;
  g.records[0].text = "hello";
  const Bytes good = datagram(kGdosChannel, encode(g));
  sub.handle_datagram(good.data(), good.size(), sink);
  Bytes bad = encode(g);
  set32(bad, 16, 0);  // host length
  for (int i = 0; i < 20; ++i) {
    const Bytes d = datagram(kGdosChannel, bad);
    sub.handle_datagram(d.data(), d.size(), sink);
  }
  const Bytes frag = {'L', 'C', '0', '3', 0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 'R', 0};
  sub.handle_datagram(frag.data(), frag.size(), sink);
  Bytes ann = encode(an_announce());
  set32(ann, kHostAt, 0);
  const Bytes bad_ann = datagram("TIMS_ANNOUNCE", ann);
  sub.handle_datagram(bad_ann.data(), bad_ann.size(), sink);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].text, "hello");
  const auto c = sub.counters();
  EXPECT_EQ(c.malformed, 20u);
  EXPECT_EQ(c.lcm_fragments, 1u);
  EXPECT_EQ(c.bad_announcements, 1u);
  const std::string w = sub.take_warnings();
  // Twenty bad batches, one warning line (at most one per kind per second).
  std::size_t lines = 0;
  for (auto at = w.find("malformed batch"); at != std::string::npos; at = w.find("malformed batch", at + 1)) ++lines;
  EXPECT_EQ(lines, 1u) << w;
  EXPECT_NE(w.find("host at byte 16: string length 0"), std::string::npos) << w;
}

TEST(GdosDatagramTest, NetworkTextReachesTheTerminalWithoutControlCharacters) {
  GdosRecord r;
  r.host = "h\x1b]0;owned\x07";
  r.name = "gen";
  r.text =
      "a\x1b[2Jb\tc\xc2\x9b"
      "31m\x7f \xc3\xa9";  // ESC, tab, C1 CSI, DEL, an e-acute
  const std::string line = gdos_view::text_line(r, r.name, false);
  EXPECT_EQ(line.find('\x1b'), std::string::npos) << line;
  EXPECT_EQ(line.find('\x07'), std::string::npos) << line;
  EXPECT_NE(line.find("a\\x1b[2Jb\tc\\x9b31m\\x7f \xc3\xa9"), std::string::npos) << line;
  EXPECT_NE(line.find("h\\x1b]0;owned\\x07"), std::string::npos) << line;
}

// Several top routers share a fleet (issue 23): only the live one with the lowest host
// id answers NOT_AVAILABLE for a robot nobody knows; the others stand by.
class TopRouterTest : public ::testing::Test {
 protected:
  void make(uint8_t host_id, int64_t warmup_ns = 0) {
    LcmTransportConfig c;
    c.url = kNoNetwork;
    c.role = NodeRole::kTopRouter;
    c.warmup_ns = warmup_ns;
    c.warn = [this](const std::string& s) { warnings += s + "\n"; };
    transport = std::make_unique<LcmTransport>(router, c);
    HostInfo self;
    self.host = "base";
    self.system = 0;
    self.host_id = host_id;
    self.executor = Address::make(0, classes::kExecutor, host_id);
    transport->set_announcement(self);
  }
  // A GET_STATUS from a tool to Generator(7/0), as a tims_packet in an LCM datagram.
  void request_to_unknown_robot() {
    packet(Address::make(7, class_ids::kGenerator, 0), Address::make(kToolSystem, classes::kTool, 1, 0), 0x7001);
  }
  void packet(Address dest, Address src, int64_t origin) {
    const MessageHeader h = make_header(dest, src, msg::kGetStatus, 0, static_cast<uint8_t>(++seq), 0);
    Bytes p(50 + sizeof h, 0);
    const auto put = [&](std::size_t at, uint64_t v, int bytes) {
      for (int i = 0; i < bytes; ++i)
        p[at + static_cast<std::size_t>(i)] = static_cast<uint8_t>(v >> (8 * (bytes - 1 - i)));
    };
    put(0, static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
    put(8, static_cast<uint64_t>(origin), 8);  // origin
    put(24, static_cast<uint64_t>(seq), 4);    // packet sequence
    put(28, static_cast<uint64_t>(seq), 4);    // message sequence
    put(32, sizeof h, 4);                      // total
    put(36, sizeof h, 4);                      // encoded
    put(46, sizeof h, 4);                      // chunk size
    std::memcpy(p.data() + 50, &h, sizeof h);
    const Bytes d = datagram("TIMS", p);
    transport->handle_datagram(d.data(), d.size());
  }
  void top_router_heard(uint8_t host_id, int64_t origin) {
    auto a = an_announce();
    a.origin = origin;
    a.role = static_cast<int8_t>(NodeRole::kTopRouter);
    a.host = "base" + std::to_string(host_id);
    a.host_id = host_id;
    a.executor = static_cast<int32_t>(Address::make(0, classes::kExecutor, host_id).raw());
    a.components.clear();
    a.count = 0;
    const Bytes d = datagram("TIMS_ANNOUNCE", encode(a));
    transport->handle_datagram(d.data(), d.size());
  }

  Router router{0};
  std::string warnings;
  std::unique_ptr<LcmTransport> transport;
  int seq = 0;
};

TEST_F(TopRouterTest, AloneItAnswersForARobotNobodyKnows) {
  make(1);
  request_to_unknown_robot();
  EXPECT_EQ(transport->counters().not_available, 1u) << warnings;
  EXPECT_EQ(transport->counters().malformed, 0u) << warnings;
}

TEST_F(TopRouterTest, OneWithALowerHostIdAnswersInstead) {
  make(1);
  top_router_heard(0, 0x5000);
  ASSERT_EQ(transport->hosts().size(), 1u) << warnings;
  request_to_unknown_robot();
  EXPECT_EQ(transport->counters().not_available, 0u) << "two top routers answered the same request";
  EXPECT_EQ(transport->counters().malformed, 0u) << warnings;
}

TEST_F(TopRouterTest, AJustStartedLowerOneIsCoveredUntilItsWarmUpHasPassed) {
  make(1, 60'000'000'000);  // a minute's warm-up: base0 below has only just started
  top_router_heard(0, 0x5000);
  request_to_unknown_robot();
  EXPECT_EQ(transport->counters().not_available, 1u) << "nobody would answer while base0 warms up";
}

// The periodic announcement of a known host does not rebuild the table of component
// owners (issue 23: that made each host's work grow with the square of the fleet), but
// one that changes the host's components does: a source is judged by its new owner.
TEST_F(TopRouterTest, AChangedComponentListIsTakenOverByTheOwnersTable) {
  make(0);
  const Address gen0 = Address::make(1, class_ids::kGenerator, 0), gen1 = Address::make(1, class_ids::kGenerator, 1);
  auto a = an_announce();  // origin 0x1234 owns Generator(1/0)
  a.system = 1;
  a.executor = static_cast<int32_t>(Address::make(1, classes::kExecutor, 3).raw());
  a.components[0].address = static_cast<int32_t>(gen0.raw());
  const Bytes first = datagram("TIMS_ANNOUNCE", encode(a));
  for (int i = 0; i < 3; ++i) transport->handle_datagram(first.data(), first.size());  // periodic: no change
  packet(Address::make(1, class_ids::kMonitor, 0), gen0, 0x9999);                      // not from its owner
  EXPECT_EQ(transport->counters().forged, 1u) << warnings;
  a.components[0].address = static_cast<int32_t>(gen1.raw());  // the host now runs Generator(1/1)
  const Bytes d = datagram("TIMS_ANNOUNCE", encode(a));
  transport->handle_datagram(d.data(), d.size());
  packet(Address::make(1, class_ids::kMonitor, 0), gen0, 0x9999);  // nobody owns it now
  EXPECT_EQ(transport->counters().forged, 1u) << warnings;
  packet(Address::make(1, class_ids::kMonitor, 0), gen1, 0x9999);
  EXPECT_EQ(transport->counters().forged, 2u) << warnings;
  EXPECT_EQ(transport->counters().malformed, 0u) << warnings;
}

TEST_F(TopRouterTest, OneWithAHigherHostIdStandsBy) {
  make(0);
  top_router_heard(1, 0x5001);
  top_router_heard(2, 0x5002);
  request_to_unknown_robot();
  EXPECT_EQ(transport->counters().not_available, 1u) << warnings;
}

}  // namespace
}  // namespace rack::tims
