// Access control (rule table, token buckets, router integration) and authenticated
// links (key files, MAC, replay window, rotation).
#include "rack/components/class_ids.h"
#include "rack/tims/access.h"
#include "rack/core/host_config.h"
#include "rack/components/builtin.h"

#include <gtest/gtest.h>
#include "hostile_files.h"
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "rack/tims/endpoint.h"
#include "rack/tims/link_auth.h"
#include "rack/tims/router.h"
#include "test_support.h"

namespace rack::tims {
namespace {

using rack::ComponentRegistry;
using rack::LoadResult;
namespace components = rack::components;
namespace rt = rack::rt;

constexpr Address kChassis = Address::make(0, class_ids::kChassis, 0, 0);
constexpr Address kPilot = Address::make(0, class_ids::kPilot, 0, 0);
constexpr Address kJoystick = Address::make(0, class_ids::kJoystick, 0, 0);
constexpr Address kTool = Address::make(kToolSystem, classes::kTool, 7, 2);
constexpr int8_t kMove = 21;
constexpr int64_t kSec = 1'000'000'000;

MessageHeader header(Address dest, Address src, int8_t type, uint8_t priority = 0, std::size_t body = 0) {
  return make_header(dest, src, type, priority, 1, body);
}

AddressMask component(Address a) { return AddressMask{a.component().raw(), 0xFFFFFF00u}; }

AccessRuleConfig rule(const std::string& name, Address to) {
  AccessRuleConfig r;
  r.name = name;
  r.to.push_back(component(to));
  return r;
}

TEST(AccessControlTest, FirstMatchingRuleDecidesBySource) {
  AccessConfig c;
  AccessRuleConfig pilot = rule("pilot", kChassis);
  pilot.from.push_back(component(kPilot));
  AccessRuleConfig others = rule("others", kChassis);
  others.any_type = false;
  others.types.set(static_cast<std::size_t>(msg::kGetStatus + 128));
  c.rules = {pilot, others};
  AccessControl ac(c);
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove), MessageOrigin::kLocal, 0).allowed());
  const auto d = ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kLocal, 0);
  EXPECT_EQ(d.verdict, AccessVerdict::kDeniedType);
  EXPECT_EQ(d.rule, 1);
  EXPECT_TRUE(ac.check(header(kChassis, kJoystick, msg::kGetStatus), MessageOrigin::kLocal, 0).allowed());
  // Replies pass a rule that lists only requests.
  EXPECT_TRUE(ac.check(header(kChassis, kJoystick, msg::kData), MessageOrigin::kLocal, 0).allowed());
  // Another destination: no rule; open by default.
  EXPECT_TRUE(ac.check(header(kPilot, kJoystick, kMove), MessageOrigin::kLocal, 0).allowed());
  const auto counters = ac.counters();
  ASSERT_EQ(counters.size(), 2u);
  EXPECT_EQ(counters[0].allowed, 1u);
  EXPECT_EQ(counters[1].denied_type, 1u);
  EXPECT_EQ(counters[1].allowed, 2u);
  EXPECT_EQ(ac.denied_total(), 1u);
  char text[120];
  ac.denial_text(d, text, sizeof text);
  EXPECT_STREQ(text, "access denied by rule 'others': message type not allowed");
}

TEST(AccessControlTest, ClosedDefaultRefusesRequestsButNotReplies) {
  AccessConfig c;
  c.default_policy = AccessDefault::kClosed;
  AccessRuleConfig tools = rule("tools", kChassis);
  tools.from.push_back(*parse_address_mask("Tool(255/*)"));
  c.rules = {tools};
  AccessControl ac(c);
  EXPECT_TRUE(ac.check(header(kChassis, kTool, msg::kOn), MessageOrigin::kNetwork, 0).allowed());
  EXPECT_EQ(ac.check(header(kChassis, kPilot, msg::kOn), MessageOrigin::kLocal, 0).verdict,
            AccessVerdict::kDeniedDefault);
  EXPECT_TRUE(ac.check(header(kPilot, kChassis, msg::kData), MessageOrigin::kLocal, 0).allowed());
  EXPECT_EQ(ac.denied_default(), 1u);
  const auto lines = ac.report();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_NE(lines[0].find("Pilot(0/0) -> Chassis(0/0) type 1 (ON)"), std::string::npos) << lines[0];
  EXPECT_TRUE(ac.report().empty()) << "nothing new since the last report";
}

TEST(AccessControlTest, LocalAndNetworkSourcesAndReplyTypes) {
  AccessConfig c;
  AccessRuleConfig net = rule("net", kChassis);
  net.from_network = true;
  net.any_type = false;
  net.types.set(static_cast<std::size_t>(msg::kGetStatus + 128));
  net.types.set(static_cast<std::size_t>(msg::kOk + 128));  // a reply type: replies restricted too
  net.restricts_replies = true;
  c.rules = {net};
  AccessControl ac(c);
  EXPECT_TRUE(ac.check(header(kChassis, kTool, kMove), MessageOrigin::kLocal, 0).allowed()) << "local: no rule";
  EXPECT_FALSE(ac.check(header(kChassis, kTool, kMove), MessageOrigin::kNetwork, 0).allowed());
  EXPECT_TRUE(ac.check(header(kChassis, kTool, msg::kOk), MessageOrigin::kNetwork, 0).allowed());
  EXPECT_FALSE(ac.check(header(kChassis, kTool, msg::kData), MessageOrigin::kNetwork, 0).allowed());
}

TEST(AccessControlTest, DeniesAbovePriority) {
  AccessConfig c;
  AccessRuleConfig r = rule("prio", kChassis);
  r.max_priority = 10;
  c.rules = {r};
  AccessControl ac(c);
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove, 10), MessageOrigin::kLocal, 0).allowed());
  EXPECT_EQ(ac.check(header(kChassis, kPilot, kMove, 11), MessageOrigin::kLocal, 0).verdict,
            AccessVerdict::kDeniedPriority);
}

TEST(AccessControlTest, RateLimitPerSourceRefillsWithTime) {
  AccessConfig c;
  AccessRuleConfig r = rule("rate", kChassis);
  r.rate = 10;  // one every 100 ms
  r.burst = 3;
  c.rules = {r};
  AccessControl ac(c);
  const int64_t t0 = 100 * kSec;
  for (int i = 0; i < 3; ++i)
    EXPECT_TRUE(ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kLocal, t0).allowed());
  EXPECT_EQ(ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kLocal, t0).verdict,
            AccessVerdict::kDeniedRate);
  // Another source has its own bucket: the flood of the first does not touch it.
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove), MessageOrigin::kLocal, t0).allowed());
  // 100 ms later one message more; 300 ms later the full burst again, not more.
  EXPECT_TRUE(ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kLocal, t0 + kSec / 10).allowed());
  EXPECT_FALSE(ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kLocal, t0 + kSec / 10).allowed());
  int passed = 0;
  for (int i = 0; i < 10; ++i)
    passed += ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kLocal, t0 + 2 * kSec).allowed() ? 1 : 0;
  EXPECT_EQ(passed, 3);
  EXPECT_EQ(ac.counters()[0].denied_rate, 9u);
}

TEST(AccessControlTest, BandwidthLimitCountsBytes) {
  AccessConfig c;
  AccessRuleConfig r = rule("bw", kChassis);
  r.bandwidth = 10000;  // 10 kB/s
  r.burst_bytes = 3000;
  c.rules = {r};
  AccessControl ac(c);
  const int64_t t0 = 50 * kSec;
  // 1016-byte messages (16-byte header + 1000): two fit the 3000-byte burst, the third not.
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove, 0, 1000), MessageOrigin::kLocal, t0).allowed());
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove, 0, 1000), MessageOrigin::kLocal, t0).allowed());
  EXPECT_EQ(ac.check(header(kChassis, kPilot, kMove, 0, 1000), MessageOrigin::kLocal, t0).verdict,
            AccessVerdict::kDeniedBandwidth);
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove, 0, 1000), MessageOrigin::kLocal, t0 + kSec / 5).allowed());
}

TEST(AccessControlTest, ManySourcesShareTheOverflowBucketNotTheEstablishedOnes) {
  AccessConfig c;
  AccessRuleConfig r = rule("rate", kChassis);
  r.rate = 1;
  r.burst = 1;
  c.rules = {r};
  c.sources = 16;
  AccessControl ac(c);
  const int64_t t0 = 10 * kSec;
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove), MessageOrigin::kLocal, t0).allowed());
  // A crowd of forged sources: at most the table's entries plus one overflow message pass.
  int passed = 0;
  for (uint32_t i = 0; i < 1000; ++i) {
    passed += ac.check(header(kChassis, Address::make(9, 0x90, static_cast<uint8_t>(i), static_cast<uint8_t>(i >> 8)),
                              kMove),
                       MessageOrigin::kNetwork, t0)
                      .allowed()
                  ? 1
                  : 0;
  }
  EXPECT_LE(passed, 16);
  EXPECT_GT(ac.overflow_uses(), 0u);
  // The established source still has its own entry: refilled after a second, allowed.
  EXPECT_TRUE(ac.check(header(kChassis, kPilot, kMove), MessageOrigin::kLocal, t0 + kSec).allowed());
}

TEST(AccessControlTest, RefusedRequestsAreAnsweredAtABoundedRate) {
  AccessConfig c;
  AccessRuleConfig r = rule("none", kChassis);
  r.any_type = false;
  c.rules = {r};
  AccessControl ac(c);
  const int64_t t0 = 20 * kSec;
  int answered = 0;
  for (int i = 0; i < 200; ++i)
    answered += ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kNetwork, t0).answer ? 1 : 0;
  EXPECT_EQ(answered, AccessControl::kRepliesPerSecond) << "a flood is not echoed";
  EXPECT_EQ(ac.counters()[0].denied_type, 200u) << "but every refusal is counted";
  EXPECT_TRUE(ac.check(header(kChassis, kJoystick, kMove), MessageOrigin::kNetwork, t0 + kSec).answer);
  EXPECT_FALSE(ac.check(header(kChassis, kJoystick, msg::kData), MessageOrigin::kNetwork, t0 + 2 * kSec).answer)
      << "never a reply to a reply";
}

TEST(AccessControlTest, ParsesAddressPatternsAndTypes) {
  const auto all = parse_address_mask("*");
  ASSERT_TRUE(all);
  EXPECT_TRUE(all->matches(kPilot));
  const auto sys = parse_address_mask("*(0/*)");
  ASSERT_TRUE(sys);
  EXPECT_TRUE(sys->matches(kPilot));
  EXPECT_FALSE(sys->matches(kTool));
  const auto cls = parse_address_mask("Pilot(0/*)");
  ASSERT_TRUE(cls);
  EXPECT_TRUE(cls->matches(Address::make(0, class_ids::kPilot, 3, 5)));
  EXPECT_FALSE(cls->matches(kJoystick));
  const auto exact = parse_address_mask("Chassis(0/0)#1");
  ASSERT_TRUE(exact);
  EXPECT_TRUE(exact->matches(kChassis.with_mailbox(1)));
  EXPECT_FALSE(exact->matches(kChassis));
  const auto hex = parse_address_mask("0x10000000/0xff000000");
  ASSERT_TRUE(hex);
  EXPECT_TRUE(hex->matches(Address::make(0x10, 1, 2, 3)));
  EXPECT_FALSE(parse_address_mask("Nonsense(0/0)"));
  EXPECT_FALSE(parse_address_mask("Pilot(0/300)"));
  EXPECT_FALSE(parse_address_mask("pilot"));
  int8_t t = 0;
  EXPECT_TRUE(parse_message_type("get_status", t));
  EXPECT_EQ(t, msg::kGetStatus);
  EXPECT_TRUE(parse_message_type("21", t));
  EXPECT_EQ(t, 21);
  EXPECT_TRUE(parse_message_type("data", t));
  EXPECT_EQ(t, msg::kData);
  EXPECT_FALSE(parse_message_type("move", t));
  EXPECT_FALSE(parse_message_type("300", t));
}

TEST(AccessControlTest, RouterAnswersADeniedRequestWithErrorAndDropsANotification) {
  AccessConfig c;
  AccessRuleConfig r = rule("chassis", kChassis);
  r.from.push_back(component(kPilot));
  AccessRuleConfig deny = rule("chassis-others", kChassis);
  deny.any_type = false;  // no types: every request refused
  c.rules = {r, deny};
  AccessControl ac(c);
  Router router(0);
  Mailbox chassis(kChassis, 8, 512), joystick(kJoystick, 8, 512);
  router.add(chassis);
  router.add(joystick);
  router.set_access(&ac);
  Endpoint ep(router, joystick, 0);
  std::array<std::byte, 512> buf{};
  const auto reply = ep.call(kChassis, kMove, buf, kSec);
  ASSERT_EQ(reply.status, CallStatus::kOk);
  EXPECT_EQ(reply.reply.type, msg::kError);
  const std::string reason(reinterpret_cast<const char*>(reply.body.data()));
  EXPECT_EQ(reason, "access denied by rule 'chassis-others': message type not allowed");
  EXPECT_EQ(chassis.queued(), 0u) << "a denied message never reaches the component";
  EXPECT_EQ(chassis.counters().denied, 1u);
  EXPECT_EQ(router.counters().denied, 1u);
  // A notification from the network: dropped without a reply.
  std::array<std::byte, sizeof(MessageHeader)> raw{};
  const MessageHeader n = make_header(kChassis, kJoystick, msg::kData, 0, 0, 0);
  std::memcpy(raw.data(), &n, sizeof n);
  EXPECT_EQ(router.deliver_local(raw), SendStatus::kOk) << "replies and notifications pass a request-only rule";
  router.set_access(nullptr);
  router.remove(kChassis);
  router.remove(kJoystick);
}

TEST(AccessControlTest, ConcurrentChecksFromManyThreadsKeepTheRate) {
  test::Watchdog watchdog(std::chrono::seconds(20));
  AccessConfig c;
  AccessRuleConfig r = rule("rate", kChassis);
  r.rate = 1;
  r.burst = 100;
  c.rules = {r};
  AccessControl ac(c);
  std::atomic<int> passed{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 1000; ++i) {
        if (ac.check(header(kChassis, kPilot, kMove), MessageOrigin::kLocal, 1000 * kSec).allowed()) ++passed;
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(passed.load(), 100) << "the burst, exactly, whatever the interleaving";
}

// ------------------------------------------------------------------ link authentication

class LinkAuthTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = "/tmp/rack_link_auth_" + std::to_string(getpid()) + "_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text, mode_t mode = 0600) {
    const std::string p = dir_ + "/" + name;
    std::ofstream(p) << text;
    chmod(p.c_str(), mode);
    return p;
  }
  static std::string key_line(char fill) { return std::string(64, fill) + "\n"; }
  std::string dir_;
};

TEST_F(LinkAuthTest, KeyFileMustBePrivateAndWellFormed) {
  const auto ok = load_key_file(write("ok", "# comment\n" + key_line('a')));
  EXPECT_TRUE(ok.error.empty()) << ok.error;
  EXPECT_EQ(ok.keys.size(), 1u);
  const auto open = load_key_file(write("open", key_line('a'), 0644));
  EXPECT_NE(open.error.find("has mode 0644"), std::string::npos) << open.error;
  EXPECT_NE(open.error.find(dir_ + "/open"), std::string::npos) << open.error;
  EXPECT_NE(load_key_file(write("short", "abcd\n")).error.find("line 1"), std::string::npos);
  EXPECT_NE(load_key_file(write("nothex", std::string(63, 'a') + "g\n")).error.find("hex"), std::string::npos);
  EXPECT_NE(load_key_file(write("three", key_line('a') + key_line('b') + key_line('c'))).error.find("more than two"),
            std::string::npos);
  EXPECT_NE(load_key_file(write("empty", "# nothing\n")).error.find("no key"), std::string::npos);
  EXPECT_NE(load_key_file(dir_ + "/missing").error.find("cannot open"), std::string::npos);
  const std::string gen = dir_ + "/generated";
  EXPECT_EQ(generate_key_file(gen), "");
  struct stat st {};
  ASSERT_EQ(stat(gen.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_TRUE(load_key_file(gen).error.empty());
  EXPECT_NE(generate_key_file(gen), "") << "never overwrites";
}

// Issue 17: open() of a FIFO as key file waited for a writer for ever.
TEST_F(LinkAuthTest, KeyFilesThatAreFifosOrDevicesAreRefusedWithoutWaiting) {
  const std::string fifo = dir_ + "/fifo.key";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  test::HangGuard guard("load_key_file on a FIFO");
  EXPECT_EQ(load_key_file(fifo).error, fifo + ": the key file is a FIFO, not a regular file");
  EXPECT_EQ(load_key_file("/dev/zero").error, "/dev/zero: the key file is a character device, not a regular file");
  const std::string big = write("big.key", std::string(70000, '#'));
  EXPECT_NE(load_key_file(big).error.find(big + ": the key file has 68.4 KiB, more than the limit of 64 KiB"),
            std::string::npos)
      << load_key_file(big).error;
  EXPECT_THROW(KeyRing ring(fifo), std::runtime_error);
}

struct Packet {
  std::vector<uint8_t> bytes;
};

Packet sign(LinkSigner& s, const std::string& payload, int64_t now) {
  Packet p;
  p.bytes.assign(payload.begin(), payload.end());
  p.bytes.resize(payload.size() + kAuthTrailerBytes);
  s.sign("TIMS", p.bytes.data(), payload.size(), p.bytes.data() + payload.size(), now);
  return p;
}

TEST_F(LinkAuthTest, MacDetectsTamperingAndReplay) {
  KeyRing ring(write("k", key_line('1')));
  LinkSigner signer(ring, 42);
  LinkVerifier verifier(ring, 5 * kSec);
  const int64_t now = 1'700'000'000 * kSec;
  const Packet a = sign(signer, "hello tims", now);
  EXPECT_EQ(verifier.verify("TIMS", a.bytes.data(), a.bytes.size(), now, 1), AuthResult::kOk);
  EXPECT_EQ(verifier.verify("TIMS", a.bytes.data(), a.bytes.size(), now, 2), AuthResult::kReplayed);
  // Every single tampered byte (payload and trailer) is caught.
  const Packet b = sign(signer, "hello tims", now);
  for (std::size_t i = 0; i < b.bytes.size(); ++i) {
    Packet t = b;
    t.bytes[i] ^= 0x01;
    const auto r = verifier.verify("TIMS", t.bytes.data(), t.bytes.size(), now, 3);
    EXPECT_NE(r, AuthResult::kOk) << "byte " << i;
  }
  EXPECT_EQ(verifier.verify("TIMS_ANNOUNCE", b.bytes.data(), b.bytes.size(), now, 3), AuthResult::kBadMac)
      << "the channel is covered";
  EXPECT_EQ(verifier.verify("TIMS", b.bytes.data(), b.bytes.size(), now, 3), AuthResult::kOk);
  const std::string plain = "hello tims, not signed at all, long enough for a trailer.............";
  EXPECT_EQ(verifier.verify("TIMS", reinterpret_cast<const uint8_t*>(plain.data()), plain.size(), now, 4),
            AuthResult::kUnsigned);
}

TEST_F(LinkAuthTest, OldSequenceAndTimeWindow) {
  KeyRing ring(write("k", key_line('2')));
  LinkSigner signer(ring, 7);
  LinkVerifier verifier(ring, 5 * kSec);
  const int64_t now = 1'700'000'000 * kSec;
  std::vector<Packet> p;
  for (int i = 0; i < 70; ++i) p.push_back(sign(signer, std::string("m").append(std::to_string(i)), now));
  // Reordering within the window of 64 is fine; each number once.
  EXPECT_EQ(verifier.verify("TIMS", p[10].bytes.data(), p[10].bytes.size(), now, 1), AuthResult::kOk);
  EXPECT_EQ(verifier.verify("TIMS", p[5].bytes.data(), p[5].bytes.size(), now, 1), AuthResult::kOk);
  EXPECT_EQ(verifier.verify("TIMS", p[5].bytes.data(), p[5].bytes.size(), now, 1), AuthResult::kReplayed);
  EXPECT_EQ(verifier.verify("TIMS", p[69].bytes.data(), p[69].bytes.size(), now, 1), AuthResult::kOk);
  EXPECT_EQ(verifier.verify("TIMS", p[4].bytes.data(), p[4].bytes.size(), now, 1), AuthResult::kReplayed)
      << "older than the 64 numbers kept";
  // Outside the time window: refused even from a sender never seen.
  LinkSigner old_signer(ring, 8);
  const Packet stale = sign(old_signer, "captured", now - 6 * kSec);
  EXPECT_EQ(verifier.verify("TIMS", stale.bytes.data(), stale.bytes.size(), now, 1), AuthResult::kOutsideWindow);
  const Packet future = sign(old_signer, "future", now + 6 * kSec);
  EXPECT_EQ(verifier.verify("TIMS", future.bytes.data(), future.bytes.size(), now, 1), AuthResult::kOutsideWindow);
}

TEST_F(LinkAuthTest, TwoKeysDuringRotationAndReload) {
  const std::string path = write("k", key_line('a'));
  KeyRing sender_ring(path);
  KeyRing receiver_ring(path);
  LinkSigner signer(sender_ring, 1);
  LinkVerifier verifier(receiver_ring, 5 * kSec);
  const int64_t now = 1'700'000'000 * kSec;
  Packet p = sign(signer, "old key", now);
  EXPECT_EQ(verifier.verify("TIMS", p.bytes.data(), p.bytes.size(), now, 1), AuthResult::kOk);
  // Step 2 of a rotation on the sender only: new key first (signs), old second.
  const std::string rotated = write("k2", key_line('b') + key_line('a'));
  std::filesystem::rename(rotated, path);
  EXPECT_NE(sender_ring.check_reload().find("reloaded: 2 key(s)"), std::string::npos);
  p = sign(signer, "new key", now);
  EXPECT_EQ(verifier.verify("TIMS", p.bytes.data(), p.bytes.size(), now, 1), AuthResult::kUnknownKey)
      << "the receiver has not reloaded yet";
  EXPECT_NE(receiver_ring.check_reload(), "");
  p = sign(signer, "new key", now);
  EXPECT_EQ(verifier.verify("TIMS", p.bytes.data(), p.bytes.size(), now, 1), AuthResult::kOk);
  // A packet signed with the old key is still accepted (second key)...
  KeyRing old_ring(write("old", key_line('a')));
  LinkSigner old_signer(old_ring, 2);
  p = sign(old_signer, "old", now);
  EXPECT_EQ(verifier.verify("TIMS", p.bytes.data(), p.bytes.size(), now, 1), AuthResult::kOk);
  // ...until the old key leaves the file.
  std::filesystem::rename(write("k3", key_line('b')), path);
  EXPECT_NE(receiver_ring.check_reload(), "");
  p = sign(old_signer, "old", now);
  EXPECT_EQ(verifier.verify("TIMS", p.bytes.data(), p.bytes.size(), now, 1), AuthResult::kUnknownKey);
  // A reload that would make the file readable by others is refused; the keys stay.
  chmod(path.c_str(), 0644);
  std::filesystem::rename(write("k4", key_line('c'), 0644), path);
  EXPECT_NE(receiver_ring.check_reload().find("keeping the keys"), std::string::npos);
  p = sign(signer, "b", now);
  EXPECT_EQ(verifier.verify("TIMS", p.bytes.data(), p.bytes.size(), now, 1), AuthResult::kOk);
  EXPECT_THROW(KeyRing refused(path), std::runtime_error);
}

// ------------------------------------------------------------------ the host file's access section

class AccessHostFileTest : public LinkAuthTest {
 protected:
  AccessHostFileTest() {
    components::register_builtin(registry_);
    caps_.online_cpus = {0, 1};
  }
  LoadResult load(const std::string& text) { return load_host_text(text, "host.yaml", registry_, caps_); }
  std::string errors(const LoadResult& r) {
    std::string all;
    for (const auto& e : r.errors) all += e.str() + "\n";
    return all;
  }
  static constexpr const char* kComponents = R"(components:
  - name: generator
    class: Generator
    data_task: {priority: 60, period_ms: 10}
  - name: monitor
    class: Monitor
    data_task: {priority: 50}
    params: {source: generator}
)";
  ComponentRegistry registry_;
  rt::RtCapabilities caps_;
};

TEST_F(AccessHostFileTest, RulesResolveNamesPatternsAndTypes) {
  const LoadResult r = load(std::string(kComponents) + R"yaml(access:
  default: closed
  log_ms: 200
  rules:
    - name: reads
      to: generator
      from: [monitor, "Tool(255/*)", network]
      types: [on, get_cont_data, 21, data]
      max_priority: 20
      rate: 100
      burst: 5
      bandwidth_kib: 64
)yaml");
  ASSERT_TRUE(r.host) << errors(r);
  const auto& a = r.host->settings.access;
  EXPECT_TRUE(r.host->settings.access_configured);
  EXPECT_EQ(a.default_policy, AccessDefault::kClosed);
  EXPECT_EQ(r.host->settings.access_log_ns, 200'000'000);
  ASSERT_EQ(a.rules.size(), 1u);
  const auto& rule = a.rules[0];
  ASSERT_EQ(rule.to.size(), 1u);
  EXPECT_TRUE(rule.to[0].matches(Address::make(0, class_ids::kGenerator, 0, 3)));
  ASSERT_EQ(rule.from.size(), 2u);
  EXPECT_TRUE(rule.from[0].matches(Address::make(0, class_ids::kMonitor, 0, 1)));
  EXPECT_TRUE(rule.from_network);
  EXPECT_FALSE(rule.any_type);
  EXPECT_TRUE(rule.types.test(21 + 128));
  EXPECT_TRUE(rule.restricts_replies);
  EXPECT_EQ(rule.max_priority, 20);
  EXPECT_DOUBLE_EQ(rule.bandwidth, 65536.0);
}

TEST_F(AccessHostFileTest, BadRulesAreRejectedWithLineAndColumn) {
  const LoadResult r = load(std::string(kComponents) + R"yaml(access:
  default: ajar
  rules:
    - name: rackd
      to: nosuch
      types: [move]
      burst: 3
      colour: red
)yaml");
  EXPECT_FALSE(r.host);
  const std::string all = errors(r);
  EXPECT_NE(all.find("host.yaml:10:12: 'default' must be open or closed"), std::string::npos) << all;
  EXPECT_NE(all.find("host.yaml:12:13: the rule name 'rackd' is rackd's own"), std::string::npos) << all;
  EXPECT_NE(all.find("host.yaml:13:11: 'nosuch' in 'to' is neither a component"), std::string::npos) << all;
  EXPECT_NE(all.find("host.yaml:14:15: 'move' is not a message type"), std::string::npos) << all;
  EXPECT_NE(all.find("'burst' without 'rate'"), std::string::npos) << all;
  EXPECT_NE(all.find("host.yaml:16:7: unknown key 'colour' in an access rule"), std::string::npos) << all;
}

TEST_F(AccessHostFileTest, KeyFileIsCheckedAtLoad) {
  const std::string good = write("good.key", key_line('e'));
  const std::string open = write("open.key", key_line('e'), 0640);
  const auto host = [&](const std::string& key) {
    return std::string(
               "tims:\n  networks:\n    - {name: robot, url: \"udpm://239.255.76.67:7667?ttl=0\", key_file: \"") +
           key + "\"}\n" + kComponents;
  };
  LoadResult r = load(host(good));
  ASSERT_TRUE(r.host) << errors(r);
  EXPECT_EQ(r.host->settings.networks.at(0).key_file, good);
  r = load(host(open));
  EXPECT_FALSE(r.host);
  EXPECT_NE(errors(r).find("host.yaml:3:71: key file " + open + ": has mode 0640"), std::string::npos) << errors(r);
}

TEST_F(AccessHostFileTest, ShippedExampleLoads) {
  std::ifstream in(std::string(RACK_SOURCE_DIR) + "/configs/access_control.yaml");
  std::ostringstream whole;
  whole << in.rdbuf();
  std::string text = whole.str();
  ASSERT_FALSE(text.empty());
  const std::string key = write("robot.key", key_line('f'));
  const std::string line = "key_file: /etc/rack/robot.key";
  const auto at = text.find(line);
  ASSERT_NE(at, std::string::npos);
  text.replace(at, line.size(), "key_file: " + key);
  const LoadResult r = load(text);
  ASSERT_TRUE(r.host) << errors(r);
  EXPECT_EQ(r.host->settings.access.rules.size(), 2u);
}

}  // namespace
}  // namespace rack::tims
