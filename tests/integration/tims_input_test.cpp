// TiMS/LCM input from outside: the real rackd on a private LCM bus, and this test as a
// hostile or foreign peer that writes raw UDP multicast datagrams in LCM's framing
// (so it can send what no LCM library would: broken fields, forged sources, other
// byte orders).
//
//  - a flood of malformed packets of every kind while a periodic task keeps its rate
//    (asserted on cycle counts with a generous tolerance, never on timings), counted,
//    logged at a bounded rate, and rackd keeps answering;
//  - a request whose header and body are in the other byte order is converted on
//    receipt (synthetic big-endian messages on this little-endian machine);
//  - a chunked message with a missing chunk is reported lost, not delivered in part.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"
#include "raw_lcm.h"
#include "shipped_host.h"
#include "rack/components/class_ids.h"
#include "rack/core/wire.h"
#include "rack/tims/message.h"
#include "rack/tims/router.h"
#include "rack_lcm/tims_packet.hpp"

namespace rack::test {
namespace {

using namespace std::chrono_literals;
using tims::Address;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

double number(const std::optional<Json>& j, const std::string& key) {
  const Json* v = j ? j->get(key) : nullptr;
  return v != nullptr && v->is_number() ? v->number : -1.0;
}
std::string text(const std::optional<Json>& j, const std::string& key) {
  const Json* v = j ? j->get(key) : nullptr;
  return v != nullptr && v->is_string() ? v->string : "";
}

struct Chunk {
  int64_t origin = 0x5eed;
  int32_t packet_seq = 1;
  int32_t message_seq = 1;
  int32_t total = 0;
  int32_t encoded = 0;
  int32_t offset = 0;
  int8_t encoding = 0;
  int8_t hops = 0;
  std::optional<int32_t> size;  // default: the bytes that follow
  uint64_t fingerprint = static_cast<uint64_t>(rack_lcm::tims_packet::getHash());
};

// A tims_packet (see tims/lcm/rack_tims.lcm), fields as given.
std::vector<uint8_t> packet(const Chunk& c, const std::vector<uint8_t>& data) {
  std::vector<uint8_t> p;
  put64(p, c.fingerprint);
  put64(p, static_cast<uint64_t>(c.origin));
  put64(p, 0);  // relay
  put32(p, static_cast<uint32_t>(c.packet_seq));
  put32(p, static_cast<uint32_t>(c.message_seq));
  put32(p, static_cast<uint32_t>(c.total));
  put32(p, static_cast<uint32_t>(c.encoded));
  put32(p, static_cast<uint32_t>(c.offset));
  p.push_back(static_cast<uint8_t>(c.encoding));
  p.push_back(static_cast<uint8_t>(c.hops));
  put32(p, static_cast<uint32_t>(c.size.value_or(static_cast<int32_t>(data.size()))));
  p.insert(p.end(), data.begin(), data.end());
  return p;
}

// A whole TiMS message as one packet.
std::vector<uint8_t> message_packet(const std::vector<uint8_t>& message, int64_t origin, int32_t seq) {
  Chunk c;
  c.origin = origin;
  c.packet_seq = seq;
  c.message_seq = seq;
  c.total = c.encoded = static_cast<int32_t>(message.size());
  return packet(c, message);
}

// TiMS header + body, the header written in the given byte order.
std::vector<uint8_t> tims_message(Address dest, Address src, int8_t type, uint8_t seq, const std::vector<uint8_t>& body,
                                  bool little_endian, bool body_little_endian) {
  tims::MessageHeader h = tims::make_header(dest, src, type, 1, seq, body.size());
  h.flags = static_cast<uint8_t>((little_endian ? tims::kFlagHeaderLittleEndian : 0) |
                                 (body_little_endian ? tims::kFlagBodyLittleEndian : 0));
  std::vector<uint8_t> m(sizeof h);
  tims::encode_header(h, little_endian, reinterpret_cast<std::byte*>(m.data()));
  m.insert(m.end(), body.begin(), body.end());
  return m;
}

constexpr const char* kHost = R"(host: input-test
system: 0
host_id: 0
heap_prefault_mib: 0
components:
  - name: generator
    class: Generator
    instance: 0
    autostart: true
    command_task: {priority: 30}
    data_task: {priority: 70, period_ms: 10}
    params: {amplitude: 2.0}
)";

class TimsInputTest : public ::testing::Test {
 protected:
  TimsInputTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  void SetUp() override {
    ASSERT_TRUE(host_.start(host_.write("host.yaml", kHost), {"--status", "1"}));
    rackd_ = &host_.rackd();
  }
  RunResult ctl(std::vector<std::string> args) { return host_.ctl(std::move(args)); }
  std::optional<Json> status(const std::string& name) {
    const RunResult r = ctl({"status", name, "--json"});
    if (r.exit_code != 0) return std::nullopt;
    return parse_json(r.out);
  }
  // The last value of `counter` in rackd's status lines ("..., malformed 12, ...").
  uint64_t transport_counter(const std::string& counter) {
    const std::string out = rackd_->out();
    const auto at = out.rfind(" " + counter + " ");
    if (at == std::string::npos) return 0;
    return std::strtoull(out.c_str() + at + counter.size() + 2, nullptr, 10);
  }

  Watchdog watchdog_;
  RackdOnBus host_;  // rackd --status 1; stopped (SIGTERM, exit 0) when the test ends
  const TempDir& dir_ = host_.dir();
  const LcmBus& bus_ = host_.bus();
  Process* rackd_ = nullptr;  // once started
};

TEST_F(TimsInputTest, FloodOfMalformedPacketsIsDroppedCountedAndThePeriodicTaskKeepsItsRate) {
  const auto before = status("generator");
  ASSERT_TRUE(before.has_value());
  const double cycles_before = number(before, "cycles");
  const auto start = std::chrono::steady_clock::now();

  RawLcm raw(bus_.port());
  std::mt19937 rng(1234);
  const auto random_bytes = [&](std::size_t n) {
    std::vector<uint8_t> v(n);
    for (auto& b : v) b = static_cast<uint8_t>(rng());
    return v;
  };
  const Address generator = Address::make(0, class_ids::kGenerator, 0);
  const Address tool = Address::make(tims::kToolSystem, tims::classes::kTool, 0x77, 0x10);
  const std::vector<uint8_t> ok_request = tims_message(generator, tool, tims::msg::kGetStatus, 1, {}, true, true);
  uint64_t sent = 0;
  int32_t seq = 0;
  // About three seconds of bursts: every kind of bad input, over and over.
  while (std::chrono::steady_clock::now() - start < 3s) {
    for (int burst = 0; burst < 20; ++burst) {
      ++seq;
      raw.send("TIMS", random_bytes(rng() % 2000));  // random bytes
      raw.send("TIMS", random_bytes(rng() % 40));    // shorter than a packet
      auto truncated = message_packet(ok_request, 0x1111, seq);
      truncated.resize(truncated.size() - 5);
      raw.send("TIMS", truncated);  // size field lies
      Chunk wrong_type;
      wrong_type.fingerprint = 0x0123456789abcdefULL;
      wrong_type.total = wrong_type.encoded = static_cast<int32_t>(ok_request.size());
      raw.send("TIMS", packet(wrong_type, ok_request));  // not a tims_packet
      Chunk huge;
      huge.total = huge.encoded = 1 << 30;
      raw.send("TIMS", packet(huge, ok_request));  // absurd lengths
      Chunk negative;
      negative.total = negative.encoded = static_cast<int32_t>(ok_request.size());
      negative.offset = -60000;
      raw.send("TIMS", packet(negative, ok_request));  // negative offset
      auto bad_len = ok_request;
      bad_len.at(12) = 99;  // header length lies
      raw.send("TIMS", message_packet(bad_len, 0x2222, seq));
      auto bad_flags = ok_request;
      bad_flags.at(0) = 0xF3;  // reserved flag bits
      raw.send("TIMS", message_packet(bad_flags, 0x2222, seq));
      // Forged: claims to come from the generator itself (a mailbox of that host).
      raw.send("TIMS", message_packet(tims_message(generator.with_mailbox(2), generator, tims::msg::kData, 0,
                                                   random_bytes(24), true, true),
                                      0x3333, seq));
      // Unknown message type: valid TiMS, the component answers ERROR and counts it.
      raw.send("TIMS", message_packet(tims_message(generator, tool, 99, 2, {}, true, true), 0x4444, seq));
      // Announcement claiming two billion components; discover request of noise.
      std::vector<uint8_t> ann;
      put64(ann, 0x1122334455667788ULL);
      put32(ann, 0x7FFFFFFF);
      raw.send("TIMS_ANNOUNCE", ann);
      raw.send("TIMS_DISCOVER", random_bytes(64));
      raw.send_raw(random_bytes(200));  // not even LCM
      sent += 13;
    }
    std::this_thread::sleep_for(5ms);
  }
  const auto elapsed = std::chrono::steady_clock::now() - start;
  // Still answering, still running the periodic task at its rate.
  const auto after = status("generator");
  ASSERT_TRUE(after.has_value()) << rackd_->err();
  ASSERT_TRUE(rackd_->running());
  const double cycles = number(after, "cycles") - cycles_before;
  const double expected = std::chrono::duration<double>(elapsed).count() / 0.010;
  // Generous: the machine is shared and the kernel is not PREEMPT_RT.
  EXPECT_GT(cycles, 0.5 * expected) << "cycles " << cycles << " of about " << expected;
  EXPECT_EQ(text(after, "state"), "ENABLED");
  EXPECT_GT(number(after, "malformed"), 0) << "the unknown type 99 was answered ERROR and counted";

  // Counted by the transport (rackd prints its counters every second).
  std::this_thread::sleep_for(1500ms);
  EXPECT_GT(transport_counter("malformed"), 1000u) << rackd_->out();
  EXPECT_GT(transport_counter("forged"), 10u) << rackd_->out();
  // Logged at a bounded rate: one line per kind per second, not one per packet.
  const std::string err = rackd_->err();
  std::size_t lines = 0;
  for (std::size_t at = err.find("TiMS/LCM: dropped"); at != std::string::npos;
       at = err.find("TiMS/LCM: dropped", at + 1)) {
    ++lines;
  }
  EXPECT_GT(lines, 0u) << err;
  EXPECT_LT(lines, 15u * 6u) << "log lines for " << sent << " bad packets:\n" << err;
  EXPECT_TRUE(contains(err, "more like it suppressed")) << err;
}

TEST_F(TimsInputTest, OtherByteOrderIsConvertedOnReceipt) {
  // SET_PARAM amplitude = 4.25 with header and body big-endian, as a big-endian host
  // would send it.
  wire::ParamRecord rec;
  wire::copy_text(rec.name, "amplitude");
  rec.kind = static_cast<uint8_t>(wire::ParamKind::kFloat);
  rec.float_value = 4.25;
  tims::swap_fields(tims::fields_of<wire::ParamRecord>, reinterpret_cast<std::byte*>(&rec), sizeof rec);
  std::vector<uint8_t> body(sizeof rec);
  std::memcpy(body.data(), &rec, sizeof rec);
  const Address generator = Address::make(0, class_ids::kGenerator, 0);
  const Address tool = Address::make(tims::kToolSystem, tims::classes::kTool, 0x55, 0x20);
  const auto msg = tims_message(generator, tool, tims::msg::kSetParam, 7, body, false, false);
  RawLcm raw(bus_.port());
  raw.send("TIMS", message_packet(msg, 0x7777, 1));
  // The value arrived converted (a native reader would see 4.25 only if converted).
  bool seen = false;
  for (int i = 0; i < 50 && !seen; ++i) {
    const RunResult r = ctl({"params", "generator", "--json"});
    seen = contains(r.out, "\"name\":\"amplitude\",\"kind\":\"float\",\"value\":4.25");
    if (!seen) std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(seen) << ctl({"params", "generator", "--json"}).describe();
}

TEST_F(TimsInputTest, ChunkedMessageWithAMissingChunkIsReportedLost) {
  // 150 000 bytes in three chunks; the middle one never arrives.
  const Address generator = Address::make(0, class_ids::kGenerator, 0);
  const Address tool = Address::make(tims::kToolSystem, tims::classes::kTool, 0x66, 0x30);
  const auto msg = tims_message(generator, tool, tims::msg::kSetParam, 3, std::vector<uint8_t>(150000 - 16, 0), true,
                                true);
  RawLcm raw(bus_.port());
  for (int32_t off : {0, 120000}) {
    Chunk c;
    c.origin = 0x8888;
    c.packet_seq = off == 0 ? 1 : 3;  // packet 2 is the missing one: a sequence gap
    c.total = c.encoded = static_cast<int32_t>(msg.size());
    c.offset = off;
    const std::size_t n = std::min<std::size_t>(60000, msg.size() - static_cast<std::size_t>(off));
    raw.send("TIMS", packet(c, std::vector<uint8_t>(msg.begin() + off, msg.begin() + off + static_cast<long>(n))));
  }
  EXPECT_TRUE(rackd_->wait_for_stderr("lost", 10s)) << rackd_->err();
  EXPECT_TRUE(contains(rackd_->err(), "1 of 3 chunks missing")) << rackd_->err();
  std::this_thread::sleep_for(1500ms);
  EXPECT_GE(transport_counter("lost"), 1u) << rackd_->out();
  EXPECT_GE(transport_counter("gaps"), 1u) << rackd_->out();
  EXPECT_TRUE(rackd_->running());
}

TEST_F(TimsInputTest, ChunkedMessageForAnotherHostIsSkippedNotReportedLost) {
  // The first of three chunks of a DATA message for a mailbox this host does not have
  // (another host's, on a shared network): its header says so, the rest would be
  // dropped unassembled, and nothing is reported lost when the rest never comes.
  const Address elsewhere = Address::make(0, class_ids::kScan3d, 5, 3);
  const Address producer = Address::make(0, class_ids::kScan3d, 6, 0);
  const auto msg = tims_message(elsewhere, producer, tims::msg::kData, 0, std::vector<uint8_t>(150000 - 16, 1), true,
                                true);
  RawLcm raw(bus_.port());
  Chunk c;
  c.origin = 0x9999;
  c.total = c.encoded = static_cast<int32_t>(msg.size());
  raw.send("TIMS", packet(c, std::vector<uint8_t>(msg.begin(), msg.begin() + 60000)));
  std::this_thread::sleep_for(2500ms);  // past the reassembly timeout, two status lines
  EXPECT_FALSE(contains(rackd_->err(), "lost")) << rackd_->err();
  EXPECT_EQ(transport_counter("lost"), 0u) << rackd_->out();
  EXPECT_GE(transport_counter("packets in"), 1u) << rackd_->out();
}

}  // namespace
}  // namespace rack::test
