// Trusted data mailboxes and subscription leases (rack/tims/trusted_sources.h,
// rack/core/data_component.h):
//  - TrustedSourcesTest: the fixed table on its own (trust, retire, late, full, the
//    rate of NOT_AVAILABLE answers) and the router refusing before a slot is taken;
//  - SubscriptionTest: an executor in this process, a generator with a short lease and
//    a monitor subscribed to it: forged samples and ERRORs and requests sent into the
//    monitor's input mailbox are refused and counted while it stays ENABLED; a
//    listener that does not renew is dropped with an ERROR, one that renews keeps one
//    slot, and a dead listener gives way to a new subscriber.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <thread>

#include "rack/components/class_ids.h"
#include "rack/core/data_component.h"
#include "rack/core/wire.h"
#include "monitor/monitor_types.h"
#include "rack/interfaces/demo.h"
#include "rack/tims/router.h"
#include "rack/tims/trusted_sources.h"
#include "test_support.h"

namespace rack {
namespace {

using namespace std::chrono_literals;
using test::HostUnderTest;
using test::Watchdog;
using tims::Address;
using tims::TrustedSources;
namespace msg = tims::msg;
using Verdict = TrustedSources::Verdict;

constexpr int64_t kSec = rt::kNsPerSec;
const Address kOwner = Address::make(0, class_ids::kMonitor, 1);
const Address kLadar = Address::make(0, class_ids::kLadar, 1);
const Address kTool = Address::make(tims::kToolSystem, tims::classes::kTool, 7, 2);

tims::MessageHeader from(Address src, int8_t type, Address dest = kOwner.with_mailbox(3)) {
  return tims::make_header(dest, src, type, 0, 0, 0);
}

TEST(TrustedSourcesTest, AcceptsTheSubscribedProducersAndItsOwnerOnly) {
  TrustedSources t(kOwner);
  const int64_t now = 100 * kSec;
  EXPECT_EQ(t.check(from(kLadar, msg::kData), now), Verdict::kForged) << "nothing trusted yet";
  ASSERT_TRUE(t.trust(kLadar.with_mailbox(3), now)) << "trusts the component, whatever mailbox is given";
  EXPECT_TRUE(t.trusts(kLadar));
  EXPECT_EQ(t.check(from(kLadar, msg::kData), now), Verdict::kAccept);
  EXPECT_EQ(t.check(from(kLadar, msg::kError), now), Verdict::kAccept);
  EXPECT_EQ(t.check(from(kLadar.with_mailbox(1), msg::kContData), now), Verdict::kAccept);
  EXPECT_EQ(t.check(from(kOwner.with_mailbox(1), -30), now), Verdict::kAccept) << "its own wake-up";
  EXPECT_EQ(t.check(from(kTool, msg::kData), now), Verdict::kForged);
  EXPECT_EQ(t.check(from(kTool, msg::kError), now), Verdict::kForged);
  EXPECT_EQ(t.check(from(Address::make(0, class_ids::kLadar, 2), msg::kData), now), Verdict::kForged)
      << "another instance of the same class";
  const auto c = t.counters();
  EXPECT_EQ(c.forged, 4u);
  EXPECT_EQ(c.requests, 0u);
  EXPECT_EQ(c.last_source, Address::make(0, class_ids::kLadar, 2).raw()) << "the last refusal is remembered";
  EXPECT_EQ(c.last_type, msg::kData);
}

TEST(TrustedSourcesTest, RefusesRequestsFromEveryone) {
  TrustedSources t(kOwner);
  const int64_t now = 100 * kSec;
  ASSERT_TRUE(t.trust(kLadar, now));
  EXPECT_EQ(t.check(from(kLadar, msg::kGetStatus), now), Verdict::kRequest) << "even from the producer";
  EXPECT_EQ(t.check(from(kTool, msg::kGetStatus), now), Verdict::kRequest);
  EXPECT_EQ(t.check(from(kOwner, msg::kOn), now), Verdict::kRequest) << "even from itself";
  const auto c = t.counters();
  EXPECT_EQ(c.requests, 3u);
  EXPECT_EQ(c.forged, 0u);
  EXPECT_EQ(c.last_type, msg::kOn);
}

TEST(TrustedSourcesTest, ARetiredProducerIsLateForAGracePeriodThenForged) {
  TrustedSources t(kOwner);
  const int64_t now = 100 * kSec;
  ASSERT_TRUE(t.trust(kLadar, now));
  t.retire(kLadar, now);
  EXPECT_FALSE(t.trusts(kLadar));
  EXPECT_EQ(t.check(from(kLadar, msg::kData), now + kSec), Verdict::kLate);
  EXPECT_EQ(t.check(from(kLadar, msg::kData), now + TrustedSources::kLateGraceNs + 1), Verdict::kForged);
  const auto c = t.counters();
  EXPECT_EQ(c.late, 1u);
  EXPECT_EQ(c.forged, 1u);
  ASSERT_TRUE(t.trust(kLadar, now + 5 * kSec)) << "subscribed again";
  EXPECT_EQ(t.check(from(kLadar, msg::kData), now + 5 * kSec), Verdict::kAccept);
}

TEST(TrustedSourcesTest, TheTableIsFixedAndReusesEntriesOnlyAfterTheGrace) {
  TrustedSources t(kOwner);
  const int64_t now = 100 * kSec;
  for (uint8_t i = 0; i < TrustedSources::kCapacity; ++i) {
    ASSERT_TRUE(t.trust(Address::make(0, class_ids::kLadar, i), now)) << int(i);
  }
  ASSERT_TRUE(t.trust(Address::make(0, class_ids::kLadar, 0), now)) << "again: the same entry";
  const Address extra = Address::make(0, class_ids::kCamera, 9);
  EXPECT_FALSE(t.trust(extra, now)) << "full";
  t.retire(Address::make(0, class_ids::kLadar, 3), now);
  EXPECT_FALSE(t.trust(extra, now + kSec)) << "a retired entry keeps its late messages apart for the grace";
  EXPECT_TRUE(t.trust(extra, now + TrustedSources::kLateGraceNs)) << "then it is reused";
  EXPECT_EQ(t.check(from(extra, msg::kData), now + 3 * kSec), Verdict::kAccept);
  EXPECT_EQ(t.check(from(Address::make(0, class_ids::kLadar, 3), msg::kData), now + 3 * kSec), Verdict::kForged);
  t.clear();
  EXPECT_EQ(t.check(from(extra, msg::kData), now + 3 * kSec), Verdict::kForged);
}

TEST(TrustedSourcesTest, NotAvailableAnswersAreRateLimited) {
  TrustedSources t(kOwner);
  const int64_t now = 100 * kSec;
  int answered = 0;
  for (int i = 0; i < 1000; ++i) answered += t.may_answer(now) ? 1 : 0;
  EXPECT_EQ(answered, TrustedSources::kAnswersPerSecond) << "a burst of one second's worth";
  EXPECT_FALSE(t.may_answer(now + kSec / 1000));
  EXPECT_TRUE(t.may_answer(now + kSec / TrustedSources::kAnswersPerSecond)) << "refilled after one interval";
}

// The router checks a data mailbox's TrustedSources before the message takes a slot:
// refused messages never queue; a request is answered NOT_AVAILABLE.
TEST(TrustedSourcesTest, TheRouterRefusesBeforeQueuing) {
  tims::Router router(0);
  tims::Mailbox input(kOwner.with_mailbox(3), 4, 256);
  TrustedSources trusted(kOwner);
  input.set_trusted_sources(&trusted);
  router.add(input);
  const Address tool_reply = Address::make(0, tims::classes::kTool, 1, 1);
  tims::Mailbox replies(tool_reply, 4, 256);
  router.add(replies);
  ASSERT_TRUE(trusted.trust(kLadar, rt::monotonic_ns()));

  const uint32_t junk = 7;
  const tims::ConstBuffer part = tims::buffer_of(junk);
  const auto header = [&](Address src, int8_t type) {
    return tims::make_header(input.address(), src, type, 0, 1, sizeof junk);
  };
  // A flood of forged samples: none queued, so it cannot push the producer's out.
  for (int i = 0; i < 100; ++i) {
    EXPECT_EQ(router.send(header(tool_reply, msg::kData), {part}), tims::SendStatus::kDenied);
  }
  EXPECT_EQ(input.queued(), 0u);
  EXPECT_EQ(router.send(header(kLadar, msg::kData), {part}), tims::SendStatus::kOk);
  EXPECT_EQ(input.queued(), 1u);
  // A request: refused, answered NOT_AVAILABLE to its source.
  EXPECT_EQ(router.send(header(tool_reply, msg::kGetStatus), {part}), tims::SendStatus::kDenied);
  EXPECT_EQ(input.queued(), 1u);
  std::byte buf[256];
  const auto r = replies.receive(buf, tims::Mailbox::kNonBlocking);
  ASSERT_EQ(r.status, tims::RecvStatus::kOk);
  EXPECT_EQ(r.header.type, msg::kNotAvailable);
  EXPECT_EQ(r.header.src, input.address().raw());
  // From the network (deliver_local) the same.
  std::byte wire[sizeof(tims::MessageHeader) + sizeof junk];
  const tims::MessageHeader h = header(kTool, msg::kError);
  std::memcpy(wire, &h, sizeof h);
  std::memcpy(wire + sizeof h, &junk, sizeof junk);
  EXPECT_EQ(router.deliver_local(wire), tims::SendStatus::kDenied);
  EXPECT_EQ(input.queued(), 1u);
  EXPECT_EQ(router.counters().untrusted, 102u);
  EXPECT_EQ(trusted.counters().forged, 101u);
  EXPECT_EQ(trusted.counters().requests, 1u);
}

// data_task.lease_ms: 100 ms .. 1 day; the default is 10 s.
TEST(SubscriptionLeaseConfigTest, LeaseMsIsReadAndRangeChecked) {
  ComponentRegistry registry;
  components::register_builtin(registry);
  const auto host = [](const std::string& lease) {
    return "system: 0\nlcm: false\ncomponents:\n  - name: gen\n    class: Generator\n    instance: 1\n"
           "    data_task: {period_ms: 10" +
           lease + "}\n";
  };
  auto loaded = load_host_text(host(""), "lease.yaml", registry, rt::probe_capabilities());
  ASSERT_TRUE(loaded.errors.empty());
  ASSERT_EQ(loaded.host->components.size(), 1u);
  EXPECT_EQ(loaded.host->components[0]->settings().lease_ns, 10 * kSec);
  loaded = load_host_text(host(", lease_ms: 2500"), "lease.yaml", registry, rt::probe_capabilities());
  ASSERT_TRUE(loaded.errors.empty());
  EXPECT_EQ(loaded.host->components[0]->settings().lease_ns, 2500 * rt::kNsPerMs);
  for (const char* bad :
       {", lease_ms: 50", ", lease_ms: 0", ", lease_ms: -1", ", lease_ms: 86400001", ", lease_ms: x"}) {
    loaded = load_host_text(host(bad), "lease.yaml", registry, rt::probe_capabilities());
    ASSERT_EQ(loaded.errors.size(), 1u) << bad;
    EXPECT_NE(loaded.errors[0].str().find("lease_ms"), std::string::npos) << loaded.errors[0].str();
  }
}

// Stepped (rack/core/stepper.h): leases, renewals and expiries run on a virtual clock,
// so "4 leases" is exactly that much of it, and waiting for a message moves the clock
// to the first instant one is there.
class SubscriptionTest : public ::testing::Test {
 protected:
  static constexpr int64_t kLeaseMs = 300;

  void SetUp() override {
    host_ = std::make_unique<HostUnderTest>(R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    retry_ms: 100
    data_task: {period_ms: 10, ring: 200, max_listeners: 2, lease_ms: )" +
                                                std::to_string(kLeaseMs) + R"(}
  - name: mon
    class: Monitor
    instance: 1
    retry_ms: 100
    autostart: true
    params: {source: gen, source_period_ms: 10, silence_ms: 1000}
)",
                                            nullptr, false, test::Stepping::kStepped);
    gen_ = host_->address_of("gen");
    mon_ = host_->address_of("mon");
    ASSERT_TRUE(until([&] { return host_->status(mon_) == msg::kEnabled; }));
  }
  void TearDown() override {
    if (host_ && HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
  }
  HostUnderTest& host() { return *host_; }
  // Until `pred` holds, at most `limit` of virtual time. Returns whether it held.
  bool until(const std::function<bool()>& pred, std::chrono::milliseconds limit = 10000ms) {
    return host_->stepper().run_until(pred, limit.count() * rt::kNsPerMs);
  }
  void pause(int64_t ms) { (void)host_->stepper().run_for(ms * rt::kNsPerMs); }

  // GET_CONT_DATA for `mailbox`; the reply's type, and its lease when CONT_DATA.
  int8_t subscribe(Address mailbox, int64_t* lease_ns = nullptr) {
    wire::ContDataRequest req;
    req.period_ns = 0;
    req.mailbox = mailbox.raw();
    const auto r = host().call_with(gen_, msg::kGetContData, req);
    if (r.type == msg::kContData && lease_ns != nullptr && r.body.size() == sizeof(wire::ContDataReply)) {
      wire::ContDataReply rep;
      std::memcpy(&rep, r.body.data(), sizeof rep);
      *lease_ns = rep.lease_ns;
    }
    return r.type;
  }
  // Reads `box` until a message of `type` arrives (true) or `limit` of virtual time passes.
  bool receive_type(tims::Mailbox& box, int8_t type, std::chrono::milliseconds limit, std::string* text = nullptr) {
    std::byte buf[2048];
    return until(
        [&] {
          for (;;) {
            const auto r = box.receive(buf, tims::Mailbox::kNonBlocking);
            if (r.status != tims::RecvStatus::kOk) return false;
            if (r.header.type != type) continue;
            if (text != nullptr) *text = reinterpret_cast<const char*>(buf + sizeof(tims::MessageHeader));
            return true;
          }
        },
        limit);
  }
  uint64_t monitor_received() {
    wire::SampleHeader sh;
    interfaces::MonitorData d;
    return host().get_data(mon_, sh, d) ? d.received : 0;
  }

  std::unique_ptr<HostUnderTest> host_;
  Address gen_, mon_;
};

// Forged DATA and ERROR (from the tool's address, not the generator's) into the
// monitor's input mailbox: refused before queuing and counted; the monitor stays
// ENABLED, never goes through ERROR, and keeps taking the generator's samples.
TEST_F(SubscriptionTest, ForgedDataAndErrorAreRefusedAndCounted) {
  Watchdog dog;
  const wire::StatsReply before = host().stats(mon_);
  const Address input = mon_.with_mailbox(DataComponentBase::kInputMailbox);
  interfaces::GeneratorData fake{};
  const wire::SampleHeader sh{rt::host_time_ns(), 1};
  const tims::ConstBuffer sample[] = {tims::buffer_of(sh), tims::buffer_of(fake)};
  wire::ErrorText text;
  wire::copy_text(text.text, "producer left ENABLED");
  const tims::ConstBuffer error = tims::buffer_of(text);
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(host().endpoint().send(input, msg::kData, sample), tims::SendStatus::kDenied);
    EXPECT_EQ(host().endpoint().send(input, msg::kError, std::span<const tims::ConstBuffer>(&error, 1)),
              tims::SendStatus::kDenied);
  }
  const wire::StatsReply after = host().stats(mon_);
  EXPECT_EQ(after.input_forged - before.input_forged, 100u);
  EXPECT_EQ(after.errors, before.errors) << "a forged ERROR is not its producer's";
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
  const uint64_t received = monitor_received();
  EXPECT_TRUE(until([&] { return monitor_received() > received + 5; })) << "still taking samples";
  EXPECT_EQ(host().stats(mon_).errors, before.errors);
}

// A request into a data mailbox is answered NOT_AVAILABLE (the mailbox serves none),
// counted, and is never an ERROR of the component.
TEST_F(SubscriptionTest, ARequestIntoTheDataMailboxIsAnsweredNotAvailable) {
  Watchdog dog;
  const wire::StatsReply before = host().stats(mon_);
  const Address input = mon_.with_mailbox(DataComponentBase::kInputMailbox);
  const auto r = host().call(input, msg::kGetStatus);
  ASSERT_EQ(r.status, tims::CallStatus::kOk);
  EXPECT_EQ(r.type, msg::kNotAvailable);
  for (int i = 0; i < 20; ++i) (void)host().endpoint().send(input, msg::kOn, {});
  const wire::StatsReply after = host().stats(mon_);
  EXPECT_EQ(after.input_requests - before.input_requests, 21u);
  EXPECT_EQ(after.errors, before.errors);
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
  const uint64_t received = monitor_received();
  EXPECT_TRUE(until([&] { return monitor_received() > received + 5; })) << "still taking samples";
}

// A request into a reply mailbox (the command task's #1, the data task's #2) is
// refused silently (counted with input_requests): it cannot take the slot of a reply.
TEST_F(SubscriptionTest, ARequestIntoAReplyMailboxIsRefused) {
  Watchdog dog;
  const wire::StatsReply before = host().stats(mon_);
  for (const uint8_t mbx : {uint8_t{1}, uint8_t{2}}) {
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(host().endpoint().send(mon_.with_mailbox(mbx), msg::kGetStatus, {}), tims::SendStatus::kDenied);
    }
  }
  // A reply there is still delivered (and dropped as stale by its endpoint).
  EXPECT_EQ(host().endpoint().send(mon_.with_mailbox(1), msg::kOk, {}), tims::SendStatus::kOk);
  const wire::StatsReply after = host().stats(mon_);
  EXPECT_EQ(after.input_requests - before.input_requests, 10u);
  EXPECT_EQ(after.errors, before.errors);
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
}

// A listener that does not renew is dropped with an ERROR after its lease; the
// monitor, which the framework renews from its data task, stays subscribed across
// many leases without a single ERROR.
TEST_F(SubscriptionTest, AListenerThatDoesNotRenewIsDroppedAfterItsLease) {
  Watchdog dog;
  const uint64_t errors = host().stats(mon_).errors;
  int64_t lease = 0;
  ASSERT_EQ(subscribe(host().data_mailbox().address(), &lease), msg::kContData);
  EXPECT_EQ(lease, kLeaseMs * rt::kNsPerMs) << "the reply says how long the lease is";
  EXPECT_EQ(host().stats(gen_).listeners, 2u);
  ASSERT_TRUE(receive_type(host().data_mailbox(), msg::kData, 2000ms));
  std::string why;
  ASSERT_TRUE(receive_type(host().data_mailbox(), msg::kError, 5000ms, &why));
  EXPECT_NE(why.find("lease expired"), std::string::npos) << why;
  EXPECT_EQ(host().stats(gen_).listeners, 1u) << "the monitor's";
  EXPECT_GE(host().stats(gen_).listeners_expired, 1u);
  pause(4 * kLeaseMs);
  EXPECT_EQ(host().stats(mon_).errors, errors) << "the monitor renewed its lease all along";
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
  EXPECT_EQ(host().stats(gen_).listeners, 1u);
}

// GET_CONT_DATA again from the same mailbox renews: one listener, never a second,
// and no ERROR while it keeps renewing.
TEST_F(SubscriptionTest, RenewingFromTheSameMailboxKeepsOneListener) {
  Watchdog dog;
  const Address box = host().data_mailbox().address();
  ASSERT_EQ(subscribe(box), msg::kContData);
  for (int i = 0; i < 16; ++i) {  // 4 leases
    pause(kLeaseMs / 4);
    ASSERT_EQ(subscribe(box), msg::kContData);
    EXPECT_EQ(host().stats(gen_).listeners, 2u) << "the monitor and this one";
  }
  // Every message so far: samples only.
  std::byte buf[2048];
  int samples = 0;
  for (;;) {
    const auto r = host().data_mailbox().receive(buf, tims::Mailbox::kNonBlocking);
    if (r.status != tims::RecvStatus::kOk) break;
    EXPECT_EQ(r.header.type, msg::kData);
    ++samples;
  }
  EXPECT_GT(samples, 10);
  EXPECT_EQ(host().stats(gen_).listeners_expired, 0u);
}

// Both slots taken (the monitor and a listener that died): a new subscriber is
// refused while the dead one's lease runs, and takes its slot once it ran out.
TEST_F(SubscriptionTest, ADeadListenerGivesWayToANewOneAfterItsLease) {
  Watchdog dog;
  ASSERT_EQ(subscribe(host().data_mailbox().address()), msg::kContData);  // then never renewed
  tims::Mailbox other(Address::make(0, tims::classes::kTool, 1, 3), 64, 1024);
  host().executor().router().add(other);
  struct Remove {
    tims::Router& r;
    Address a;
    ~Remove() { r.remove(a); }
  } remove{host().executor().router(), other.address()};
  EXPECT_EQ(subscribe(other.address()), msg::kError) << "too many listeners while the lease runs";
  ASSERT_TRUE(until([&] { return subscribe(other.address()) == msg::kContData; }, 5000ms));
  EXPECT_TRUE(receive_type(other, msg::kData, 2000ms)) << "the new subscriber gets samples";
  EXPECT_EQ(host().stats(gen_).listeners, 2u);
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
}

// GET_LISTENERS lists who subscribes now: the monitor's input mailbox (from its host
// file), then a tool's mailbox with the period it asked for, until STOP_CONT_DATA. A
// component without a data task answers none; a body is refused as malformed.
TEST_F(SubscriptionTest, GetListenersListsTheSubscribersAndTheirPeriods) {
  Watchdog dog;
  auto listeners = [&] {
    const auto r = host().call(gen_, msg::kGetListeners);
    EXPECT_EQ(r.type, msg::kListeners);
    wire::ListenersReply rep;
    const std::span<const std::byte> body(reinterpret_cast<const std::byte*>(r.body.data()), r.body.size());
    const char* bad = wire::decode_listeners(body, true, rep);
    EXPECT_EQ(bad, nullptr) << bad;
    return rep;
  };
  wire::ListenersReply rep = listeners();
  EXPECT_EQ(rep.data_task, 1u);
  EXPECT_EQ(rep.period_ns, 10 * rt::kNsPerMs);
  ASSERT_EQ(rep.count, 1u);
  EXPECT_EQ(rep.total, 1u);
  EXPECT_EQ(Address(rep.mailbox[0]), mon_.with_mailbox(DataComponentBase::kInputMailbox));
  EXPECT_EQ(rep.factor[0], 1u);
  EXPECT_EQ(rep.listener_period_ns[0], 10 * rt::kNsPerMs);

  const Address box = host().data_mailbox().address();
  wire::ContDataRequest req;
  req.period_ns = 50 * rt::kNsPerMs;  // every fifth sample
  req.mailbox = box.raw();
  ASSERT_EQ(host().call_with(gen_, msg::kGetContData, req).type, msg::kContData);
  rep = listeners();
  ASSERT_EQ(rep.count, 2u);
  std::size_t tool = rep.mailbox[0] == box.raw() ? 0 : 1;
  EXPECT_EQ(rep.mailbox[tool], box.raw());
  EXPECT_EQ(rep.factor[tool], 5u);
  EXPECT_EQ(rep.listener_period_ns[tool], 50 * rt::kNsPerMs);
  EXPECT_GE(rep.renewed_ago_ns[tool], 0);
  EXPECT_LT(rep.renewed_ago_ns[tool], kLeaseMs * rt::kNsPerMs);

  wire::StopContDataRequest stop;
  stop.mailbox = box.raw();
  ASSERT_EQ(host().call_with(gen_, msg::kStopContData, stop).type, msg::kOk);
  rep = listeners();
  ASSERT_EQ(rep.count, 1u);
  EXPECT_EQ(Address(rep.mailbox[0]), mon_.with_mailbox(DataComponentBase::kInputMailbox));

  const uint64_t x = 1;
  EXPECT_EQ(host().call_with(gen_, msg::kGetListeners, x).type, msg::kError) << "GET_LISTENERS takes no body";
}

// A LISTENERS reply that does not add up is refused with the reason (the client's
// check; fuzz_listeners drives the same decoder).
TEST(ListenersReplyTest, TheDecoderRefusesWhatDoesNotAddUp) {
  wire::ListenersReply r;
  r.data_task = 1;
  r.count = 1;
  r.total = 1;
  r.mailbox[0] = Address::make(0, tims::classes::kTool, 1, 1).raw();
  r.factor[0] = 1;
  auto decode = [](const wire::ListenersReply& in) -> std::string {
    wire::ListenersReply out;
    const char* bad = wire::decode_listeners(std::as_bytes(std::span(&in, 1)), true, out);
    return bad == nullptr ? "" : bad;
  };
  EXPECT_EQ(decode(r), "");
  wire::ListenersReply b = r;
  b.count = 33;
  b.total = 40;
  EXPECT_EQ(decode(b), "count is above 32");
  b = r;
  b.total = 0;
  EXPECT_EQ(decode(b), "count is above total");
  b = r;
  b.factor[0] = 0;
  EXPECT_EQ(decode(b), "a listener's factor is 0");
  b = r;
  b.mailbox[0] = 0;
  EXPECT_EQ(decode(b), "a listener's mailbox is 0");
  b = r;
  b.data_task = 0;
  EXPECT_EQ(decode(b), "listeners without a data task");
  wire::ListenersReply out;
  const std::array<std::byte, 10> short_body{};
  EXPECT_NE(wire::decode_listeners(short_body, true, out), nullptr);
}

}  // namespace
}  // namespace rack
