// The component life cycle and the generic messages, through a real in-process
// executor driven by TiMS messages from a tool mailbox (see component.h for the
// transition table tested here).
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "rack/components/class_ids.h"
#include "monitor/monitor_types.h"
#include "probe/probe_types.h"
#include "rack/interfaces/demo.h"
#include "test_support.h"

namespace rack {
namespace {

using interfaces::GeneratorData;
using interfaces::MonitorData;
using interfaces::ProbeData;
using test::HostUnderTest;
using test::Stepping;
using test::Watchdog;
using tims::Address;
using tims::CallStatus;
namespace msg = tims::msg;

class LifecycleTest : public ::testing::Test {
 protected:
  // A probe (Probe(0/1)) with the given params and retry back-off, a generator
  // (Generator(0/1), 10 ms) and, when asked, a monitor of the generator (Monitor(0/1)).
  static std::string host_yaml(const std::string& probe_params, int retry_ms = 100, bool monitor = false,
                               bool monitor_autostart = false) {
    std::string y = R"(system: 0
lcm: false
components:
  - name: probe
    class: Probe
    instance: 1
    retry_ms: )" + std::to_string(retry_ms) +
                    R"(
    data_task: {period_ms: 10, ring: 64}
    params: {)" + probe_params +
                    R"(}
  - name: gen
    class: Generator
    instance: 1
    retry_ms: 100
    data_task: {period_ms: 10, ring: 200}
)";
    if (monitor) {
      y += R"(  - name: mon
    class: Monitor
    instance: 1
    retry_ms: 100
    autostart: )" +
           std::string(monitor_autostart ? "true" : "false") +
           R"(
    params: {source: gen, source_period_ms: 50, silence_ms: 1000}
)";
    }
    return y;
  }

  // Stepped (rack/core/stepper.h) unless a test asks for threads: the tasks run on a
  // virtual clock, so a back-off of 100 ms is exactly 100 ms of it, and waiting for a
  // condition moves the clock to the first instant it holds instead of polling.
  void start(const std::string& probe_params = "", int retry_ms = 100, bool monitor = false,
             bool monitor_autostart = false, Stepping stepping = Stepping::kStepped) {
    stepping_ = stepping;
    host_ = std::make_unique<HostUnderTest>(host_yaml(probe_params, retry_ms, monitor, monitor_autostart), nullptr,
                                            false, stepping);
    probe_ = host_->address_of("probe");
    gen_ = host_->address_of("gen");
    if (monitor) mon_ = host_->address_of("mon");
  }
  void TearDown() override {
    if (host_ && HasFailure()) std::fprintf(stderr, "executor log:\n%s", host_->log().c_str());
    host_.reset();
  }

  HostUnderTest& host() { return *host_; }
  // Until `pred` holds, at most `limit_ns` (virtual time when stepped, real time polled
  // with threads). Returns whether it held.
  bool until(const std::function<bool()>& pred, int64_t limit_ns = 10 * rt::kNsPerSec) {
    if (stepping_ == Stepping::kStepped) return host_->stepper().run_until(pred, limit_ns);
    return test::eventually(pred, std::chrono::milliseconds(limit_ns / rt::kNsPerMs));
  }
  // Lets `ms` pass: the tasks run that long (virtual time when stepped).
  void pause(int ms) {
    if (stepping_ == Stepping::kStepped) (void)host_->stepper().run_for(ms * rt::kNsPerMs);
    else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
  }

  // Waits for a sample of `dest` newer than `after` (sequence), up to 10 s.
  template <typename T>
  std::optional<std::pair<wire::SampleHeader, T>> next_sample(Address dest, int64_t after = -1) {
    std::optional<std::pair<wire::SampleHeader, T>> out;
    until([&] {
      wire::SampleHeader h;
      T s;
      if (!host_->get_data(dest, h, s)) return false;
      if (static_cast<int64_t>(h.sequence) <= after) return false;
      out.emplace(h, s);
      return true;
    });
    return out;
  }

  struct Streamed {
    tims::MessageHeader header;
    wire::SampleHeader sample;
    std::string body;
  };
  // The next message in the tool's data mailbox, within `timeout_ns` (of virtual time
  // when stepped).
  std::optional<Streamed> receive_streamed(int64_t timeout_ns = test::kCallTimeoutNs) {
    alignas(8) std::array<std::byte, 1024> buf{};
    if (stepping_ == Stepping::kStepped && timeout_ns > 0) {
      (void)until([&] { return host_->data_mailbox().queued() > 0; }, timeout_ns);
      timeout_ns = tims::Mailbox::kNonBlocking;
    }
    const auto r = host_->data_mailbox().receive(buf, timeout_ns);
    if (r.status != tims::RecvStatus::kOk) return std::nullopt;
    Streamed s;
    s.header = r.header;
    s.body.assign(reinterpret_cast<const char*>(buf.data()) + sizeof(tims::MessageHeader),
                  r.length - sizeof(tims::MessageHeader));
    if (s.body.size() >= sizeof s.sample) std::memcpy(&s.sample, s.body.data(), sizeof s.sample);
    return s;
  }
  void drain_stream() {
    while (receive_streamed(tims::Mailbox::kNonBlocking)) {
    }
  }

  std::unique_ptr<HostUnderTest> host_;
  Stepping stepping_ = Stepping::kStepped;
  Address probe_, gen_, mon_;
};

TEST_F(LifecycleTest, OnSwitchesDisabledToEnabledAndOffBack) {
  Watchdog dog;
  start();
  EXPECT_EQ(host().status(probe_), msg::kDisabled);
  const auto on = host().call(probe_, msg::kOn);
  ASSERT_EQ(on.status, CallStatus::kOk);
  EXPECT_EQ(on.type, msg::kOk);
  EXPECT_EQ(host().status(probe_), msg::kEnabled);
  EXPECT_EQ(host().stats(probe_).state, static_cast<uint8_t>(ComponentState::kEnabled));
  // ON while ENABLED is answered OK and changes nothing.
  EXPECT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
  const auto s = next_sample<ProbeData>(probe_);
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->second.on_calls, 1);
  EXPECT_GE(s->second.loops, 1);

  EXPECT_EQ(host().call(probe_, msg::kOff).type, msg::kOk);
  EXPECT_EQ(host().status(probe_), msg::kDisabled);
  EXPECT_EQ(host().stats(probe_).errors, 0u);
  // The other component was never touched.
  EXPECT_EQ(host().status(gen_), msg::kDisabled);
}

TEST_F(LifecycleTest, FailingOnGoesToErrorThenRetriesUntilOnSucceeds) {
  Watchdog dog;
  start("fail_on: true", /*retry_ms=*/100);
  const auto on = host().call(probe_, msg::kOn);
  ASSERT_EQ(on.status, CallStatus::kOk);
  EXPECT_EQ(on.type, msg::kError);
  EXPECT_NE(on.error_text().find("on() failed"), std::string::npos) << on.error_text();
  EXPECT_EQ(host().status(probe_), msg::kError);
  // Retries keep failing while fail_on is set (ERROR -> ERROR).
  pause(350);
  EXPECT_EQ(host().status(probe_), msg::kError);
  // Fix the cause: the next retry switches it on with nobody asking.
  EXPECT_EQ(host().set_bool(probe_, "fail_on", false).type, msg::kOk);
  EXPECT_TRUE(until([&] { return host().status(probe_) == msg::kEnabled; }));
  const auto s = next_sample<ProbeData>(probe_);
  ASSERT_TRUE(s.has_value());
  EXPECT_GE(s->second.on_calls, 3) << "the first ON, at least one failed retry, the good retry";
  EXPECT_GE(s->second.off_calls, 2) << "off() undoes every failed on()";
  EXPECT_EQ(host().stats(probe_).errors, 1u) << "ERROR was entered once";
}

TEST_F(LifecycleTest, ThrowingOnGoesToErrorThenRetriesUntilOnSucceeds) {
  Watchdog dog;
  start("throw_on: true", /*retry_ms=*/100);
  const auto on = host().call(probe_, msg::kOn);
  ASSERT_EQ(on.status, CallStatus::kOk);
  EXPECT_EQ(on.type, msg::kError);
  EXPECT_EQ(host().status(probe_), msg::kError);
  pause(350);
  EXPECT_EQ(host().status(probe_), msg::kError);
  EXPECT_EQ(host().set_bool(probe_, "throw_on", false).type, msg::kOk);
  EXPECT_TRUE(until([&] { return host().status(probe_) == msg::kEnabled; }));
  const auto s = next_sample<ProbeData>(probe_);
  ASSERT_TRUE(s.has_value());
  EXPECT_GE(s->second.on_calls, 3);
}

TEST_F(LifecycleTest, OnFromErrorRunsAtOnce) {
  Watchdog dog;
  start("fail_on: true", /*retry_ms=*/60000);  // no retry during the test
  EXPECT_EQ(host().call(probe_, msg::kOn).type, msg::kError);
  EXPECT_EQ(host().status(probe_), msg::kError);
  EXPECT_EQ(host().set_bool(probe_, "fail_on", false).type, msg::kOk);
  EXPECT_EQ(host().status(probe_), msg::kError) << "no retry before the back-off";
  EXPECT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
  EXPECT_EQ(host().status(probe_), msg::kEnabled);
}

class LoopFailureTest : public LifecycleTest, public ::testing::WithParamInterface<const char*> {};

TEST_P(LoopFailureTest, EnabledGoesToErrorWhenLoopFailsAndRetries) {
  Watchdog dog;
  const char* knob = GetParam();
  start("", /*retry_ms=*/100);
  ASSERT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
  const auto before = next_sample<ProbeData>(probe_);
  ASSERT_TRUE(before.has_value());
  EXPECT_EQ(before->second.off_calls, 0);

  EXPECT_EQ(host().set_bool(probe_, knob, true).type, msg::kOk);
  // ENABLED -> ERROR, then each retry switches it on and the loop fails again: every
  // entry into ERROR is counted, so two entries prove a retry happened.
  EXPECT_TRUE(until([&] { return host().stats(probe_).errors >= 2; })) << knob;
  EXPECT_NE(host().status(probe_), msg::kDisabled);

  EXPECT_EQ(host().set_bool(probe_, knob, false).type, msg::kOk);
  EXPECT_TRUE(until([&] { return host().status(probe_) == msg::kEnabled; })) << "retry after the back-off";
  // It stays up now, and the samples show off() ran when it left ENABLED and on() ran again.
  const auto after = next_sample<ProbeData>(probe_, static_cast<int64_t>(before->first.sequence));
  ASSERT_TRUE(after.has_value());
  EXPECT_GE(after->second.off_calls, 1);
  EXPECT_GE(after->second.on_calls, 2);
  pause(150);
  EXPECT_EQ(host().status(probe_), msg::kEnabled);
}

INSTANTIATE_TEST_SUITE_P(FailOrThrow, LoopFailureTest, ::testing::Values("fail_loop", "throw_loop"));

TEST_F(LifecycleTest, OffFromErrorDisablesAndStopsRetries) {
  Watchdog dog;
  start("fail_on: true", /*retry_ms=*/50);
  EXPECT_EQ(host().call(probe_, msg::kOn).type, msg::kError);
  EXPECT_EQ(host().call(probe_, msg::kOff).type, msg::kOk);
  EXPECT_EQ(host().status(probe_), msg::kDisabled);
  // Were it still retrying, it would switch on now that on() can succeed.
  EXPECT_EQ(host().set_bool(probe_, "fail_on", false).type, msg::kOk);
  pause(400);
  EXPECT_EQ(host().status(probe_), msg::kDisabled);
}

TEST_F(LifecycleTest, ThrowingCommandPutsTheComponentInError) {
  Watchdog dog;
  start("", /*retry_ms=*/60000);
  ASSERT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
  // The echo command works.
  const uint64_t word = 0x1122334455667788;
  const auto echo = host().call_with(probe_, interfaces::kProbeEcho, word);
  ASSERT_EQ(echo.type, msg::kOk);
  ASSERT_EQ(echo.body.size(), sizeof word);
  EXPECT_EQ(0, std::memcmp(echo.body.data(), &word, sizeof word));
  // The throwing one is answered ERROR and takes the component down.
  const auto thrown = host().call(probe_, interfaces::kProbeThrow);
  ASSERT_EQ(thrown.status, CallStatus::kOk);
  EXPECT_EQ(thrown.type, msg::kError);
  EXPECT_EQ(host().status(probe_), msg::kError);
  EXPECT_EQ(host().stats(probe_).errors, 1u);
  // Only this component.
  EXPECT_EQ(host().call(gen_, msg::kOn).type, msg::kOk);
  EXPECT_EQ(host().status(gen_), msg::kEnabled);
}

TEST_F(LifecycleTest, FailedInitIsErrorForGoodAndOthersKeepWorking) {
  Watchdog dog;
  start("fail_init: true", /*retry_ms=*/50);
  EXPECT_EQ(host().status(probe_), msg::kError);
  const auto on = host().call(probe_, msg::kOn);
  ASSERT_EQ(on.status, CallStatus::kOk);
  EXPECT_EQ(on.type, msg::kError);
  EXPECT_NE(on.error_text().find("init() failed"), std::string::npos) << on.error_text();
  EXPECT_NE(on.error_text().find("fail_init is set"), std::string::npos) << on.error_text();
  // fail_init is read by init() only: SET_PARAM refuses it (Spec::init_only), and
  // init() is not run again: no retries, on() is never tried.
  const auto set = host().set_bool(probe_, "fail_init", false);
  EXPECT_EQ(set.type, msg::kError);
  EXPECT_NE(set.error_text().find("read at start only"), std::string::npos) << set.error_text();
  pause(300);
  EXPECT_EQ(host().status(probe_), msg::kError);
  EXPECT_EQ(host().call(probe_, msg::kOn).type, msg::kError);
  for (const auto& v : host().executor().components()) {
    if (v.component->name() == "probe") {
      EXPECT_FALSE(v.init_error.empty());
    }
  }
  EXPECT_NE(host().log().find("init() failed"), std::string::npos);

  // The generator in the same executor is unaffected.
  EXPECT_EQ(host().call(gen_, msg::kOn).type, msg::kOk);
  EXPECT_EQ(host().status(gen_), msg::kEnabled);
  EXPECT_TRUE(next_sample<GeneratorData>(gen_).has_value());
}

TEST_F(LifecycleTest, OnIsAnsweredOnlyAfterOnFinished) {
  Watchdog dog;
  start("on_delay_ms: 300");
  const int64_t t0 = rt::monotonic_ns();
  const auto on = host().call(probe_, msg::kOn);
  const int64_t waited = rt::monotonic_ns() - t0;
  ASSERT_EQ(on.status, CallStatus::kOk);
  EXPECT_EQ(on.type, msg::kOk);
  // Ordering check with a loose bound: the reply cannot come before on() has slept.
  EXPECT_GE(waited, 250 * rt::kNsPerMs);
  EXPECT_EQ(host().status(probe_), msg::kEnabled);
}

TEST_F(LifecycleTest, GetDataGivesTheNewestOrTheNearestSample) {
  Watchdog dog;
  start();
  // Nothing published yet.
  const auto none = host().call(probe_, msg::kGetData);
  EXPECT_EQ(none.type, msg::kError);
  EXPECT_NE(none.error_text().find("no data"), std::string::npos) << none.error_text();

  ASSERT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
  const auto first = next_sample<ProbeData>(probe_);
  ASSERT_TRUE(first.has_value());
  const auto later = next_sample<ProbeData>(probe_, static_cast<int64_t>(first->first.sequence) + 2);
  ASSERT_TRUE(later.has_value());
  EXPECT_GT(later->second.loops, first->second.loops);
  EXPECT_GT(later->first.time_ns, first->first.time_ns);

  // By time: the exact time of an older sample gives that sample back.
  wire::SampleHeader h;
  ProbeData d;
  ASSERT_TRUE(host().get_data(probe_, h, d, first->first.time_ns));
  EXPECT_EQ(h.sequence, first->first.sequence);
  EXPECT_EQ(d.loops, first->second.loops);
  // Too old and too new are errors.
  wire::GetDataRequest req;
  req.time_ns = first->first.time_ns - 3600 * rt::kNsPerSec;
  EXPECT_EQ(host().call_with(probe_, msg::kGetData, req).type, msg::kError);
  req.time_ns = later->first.time_ns + 3600 * rt::kNsPerSec;
  EXPECT_EQ(host().call_with(probe_, msg::kGetData, req).type, msg::kError);
}

TEST_F(LifecycleTest, GetContDataSendsEveryNthSampleUntilStopped) {
  Watchdog dog;
  start();
  ASSERT_EQ(host().call(gen_, msg::kOn).type, msg::kOk);
  wire::ContDataRequest req;
  req.period_ns = 50 * rt::kNsPerMs;  // the generator runs every 10 ms: every 5th sample
  req.mailbox = host().data_mailbox().address().raw();
  const auto rep = host().call_with(gen_, msg::kGetContData, req);
  ASSERT_EQ(rep.type, msg::kContData);
  wire::ContDataReply period;
  ASSERT_EQ(rep.body.size(), sizeof period);
  std::memcpy(&period, rep.body.data(), sizeof period);
  EXPECT_EQ(period.period_ns, 50 * rt::kNsPerMs);
  EXPECT_EQ(host().stats(gen_).listeners, 1u);

  std::vector<uint64_t> seqs;
  while (seqs.size() < 6) {
    const auto s = receive_streamed();
    ASSERT_TRUE(s.has_value()) << "no sample within the watchdog timeout";
    EXPECT_EQ(s->header.type, msg::kData);
    EXPECT_EQ(s->header.source(), gen_);
    ASSERT_EQ(s->body.size(), sizeof(wire::SampleHeader) + sizeof(GeneratorData));
    seqs.push_back(s->sample.sequence);
  }
  for (std::size_t i = 1; i < seqs.size(); ++i) EXPECT_EQ(seqs[i] - seqs[i - 1], 5u) << "sample " << i;

  wire::StopContDataRequest stop;
  stop.mailbox = req.mailbox;
  EXPECT_EQ(host().call_with(gen_, msg::kStopContData, stop).type, msg::kOk);
  EXPECT_EQ(host().stats(gen_).listeners, 0u);
  drain_stream();  // what was sent before the stop
  EXPECT_FALSE(receive_streamed(300 * rt::kNsPerMs).has_value()) << "samples after STOP_CONT_DATA";
}

TEST_F(LifecycleTest, GetContDataWithoutPeriodSendsEverySample) {
  Watchdog dog;
  start();
  ASSERT_EQ(host().call(gen_, msg::kOn).type, msg::kOk);
  wire::ContDataRequest req;
  req.period_ns = 0;
  req.mailbox = host().data_mailbox().address().raw();
  const auto rep = host().call_with(gen_, msg::kGetContData, req);
  ASSERT_EQ(rep.type, msg::kContData);
  wire::ContDataReply period;
  std::memcpy(&period, rep.body.data(), sizeof period);
  EXPECT_EQ(period.period_ns, 10 * rt::kNsPerMs);
  const auto a = receive_streamed();
  const auto b = receive_streamed();
  ASSERT_TRUE(a && b);
  EXPECT_EQ(b->sample.sequence - a->sample.sequence, 1u);
}

TEST_F(LifecycleTest, GetContDataIsRefusedWhenNotEnabled) {
  Watchdog dog;
  start();
  wire::ContDataRequest req;
  req.period_ns = 0;
  req.mailbox = host().data_mailbox().address().raw();
  EXPECT_EQ(host().call_with(gen_, msg::kGetContData, req).type, msg::kError);
  EXPECT_EQ(host().call(gen_, msg::kGetNextData).type, msg::kError);
}

TEST_F(LifecycleTest, GetNextDataAnswersWithTheNextSample) {
  Watchdog dog;
  // Threads: the call waits for the next cycle, which a stepped executor only runs
  // when the test steps it (after the call has returned).
  start("", 100, false, false, Stepping::kThreads);
  ASSERT_EQ(host().call(gen_, msg::kOn).type, msg::kOk);
  const auto newest = next_sample<GeneratorData>(gen_);
  ASSERT_TRUE(newest.has_value());
  const auto next = host().call(gen_, msg::kGetNextData);
  ASSERT_EQ(next.status, CallStatus::kOk);
  ASSERT_EQ(next.type, msg::kData);
  ASSERT_EQ(next.body.size(), sizeof(wire::SampleHeader) + sizeof(GeneratorData));
  wire::SampleHeader h;
  std::memcpy(&h, next.body.data(), sizeof h);
  EXPECT_GT(h.sequence, newest->first.sequence);
  // One-shot: nothing else arrives and no listener is left.
  EXPECT_EQ(host().stats(gen_).listeners, 0u);
}

TEST_F(LifecycleTest, ListenerGetsErrorWhenTheProducerGoesOff) {
  Watchdog dog;
  start();
  ASSERT_EQ(host().call(gen_, msg::kOn).type, msg::kOk);
  wire::ContDataRequest req;
  req.mailbox = host().data_mailbox().address().raw();
  ASSERT_EQ(host().call_with(gen_, msg::kGetContData, req).type, msg::kContData);
  ASSERT_TRUE(receive_streamed().has_value());
  EXPECT_EQ(host().call(gen_, msg::kOff).type, msg::kOk);
  bool got_error = false;
  for (int i = 0; i < 1000 && !got_error; ++i) {
    const auto s = receive_streamed();
    ASSERT_TRUE(s.has_value()) << "no ERROR message for the listener";
    EXPECT_EQ(s->header.source(), gen_);
    if (s->header.type == msg::kError) {
      got_error = true;
      EXPECT_NE(s->body.find("left ENABLED"), std::string::npos);
    } else {
      EXPECT_EQ(s->header.type, msg::kData);
    }
  }
  EXPECT_TRUE(got_error);
  EXPECT_EQ(host().stats(gen_).listeners, 0u);
  EXPECT_FALSE(receive_streamed(200 * rt::kNsPerMs).has_value()) << "a dropped listener got more";
}

TEST_F(LifecycleTest, MonitorSwitchesItsSourceOnByCascadingOn) {
  Watchdog dog;
  start("", 100, /*monitor=*/true);
  EXPECT_EQ(host().status(gen_), msg::kDisabled);
  EXPECT_EQ(host().call(mon_, msg::kOn).type, msg::kOk);
  EXPECT_EQ(host().status(gen_), msg::kEnabled) << "the monitor switched its source on";
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
  EXPECT_EQ(host().stats(gen_).listeners, 1u);
  std::optional<std::pair<wire::SampleHeader, MonitorData>> seen;
  ASSERT_TRUE(until([&] {
    seen = next_sample<MonitorData>(mon_);
    return seen && seen->second.received >= 3;
  }));
  EXPECT_EQ(seen->second.real_period_ns, 50 * rt::kNsPerMs);
  EXPECT_GT(seen->second.source_sequence, 0u);

  // OFF unsubscribes from the producer before it is answered.
  EXPECT_EQ(host().call(mon_, msg::kOff).type, msg::kOk);
  EXPECT_EQ(host().stats(gen_).listeners, 0u);
  EXPECT_EQ(host().status(gen_), msg::kEnabled) << "OFF does not cascade";
}

TEST_F(LifecycleTest, ConsumerRecoversWhenItsProducerGoesOff) {
  Watchdog dog;
  start("", 100, /*monitor=*/true, /*monitor_autostart=*/true);
  // autostart: start() returned after the monitor's ON was answered.
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
  EXPECT_EQ(host().status(gen_), msg::kEnabled);
  EXPECT_EQ(host().call(gen_, msg::kOff).type, msg::kOk);
  // The monitor gets ERROR from the producer and leaves ENABLED ...
  EXPECT_TRUE(until([&] { return host().stats(mon_).errors >= 1; }));
  // ... then its retry switches the producer on again.
  EXPECT_TRUE(until([&] { return host().status(mon_) == msg::kEnabled; }));
  EXPECT_EQ(host().status(gen_), msg::kEnabled);
}

// A DATA message in a consumer's input mailbox that is not the sample it takes (wrong
// size: another class, a corrupt sender) is skipped and counted as malformed (and
// logged through GDOS, at most once a second); the consumer stays ENABLED and keeps taking the good samples.
// It comes in the producer's name: from any other source the input mailbox refuses it
// (subscription_test.cpp).
TEST_F(LifecycleTest, ConsumerCountsAndSkipsAMalformedSample) {
  Watchdog dog;
  start("", 100, /*monitor=*/true, /*monitor_autostart=*/true);
  ASSERT_EQ(host().status(mon_), msg::kEnabled);
  const uint64_t before = host().stats(mon_).malformed;
  const uint64_t errors = host().stats(mon_).errors;
  const uint8_t junk[5] = {1, 2, 3, 4, 5};
  const tims::ConstBuffer part{junk, sizeof junk};
  ASSERT_EQ(host().endpoint().send(mon_.with_mailbox(DataComponentBase::kInputMailbox), msg::kData,
                                   std::span<const tims::ConstBuffer>(&part, 1), /*reply_to=*/gen_),
            tims::SendStatus::kOk);
  EXPECT_TRUE(until([&] { return host().stats(mon_).malformed == before + 1; }));
  const uint64_t cycles = host().stats(mon_).data.cycles;
  EXPECT_TRUE(until([&] { return host().stats(mon_).data.cycles > cycles + 3; })) << "still consuming";
  EXPECT_EQ(host().status(mon_), msg::kEnabled);
  // The junk woke the data task with nothing usable: skipped, not taken for a silent
  // source (that is an error only after data_timeout without a good sample).
  EXPECT_EQ(host().stats(mon_).errors, errors);
}

TEST_F(LifecycleTest, GetAndSetParam) {
  Watchdog dog;
  start("label: first");
  wire::ParamName name;
  wire::copy_text(name.name, "label");
  auto r = host().call_with(probe_, msg::kGetParam, name);
  ASSERT_EQ(r.type, msg::kParam);
  wire::ParamRecord rec;
  ASSERT_EQ(r.body.size(), sizeof rec);
  std::memcpy(&rec, r.body.data(), sizeof rec);
  EXPECT_STREQ(rec.name, "label");
  EXPECT_STREQ(rec.string_value, "first");

  EXPECT_EQ(host().set_param(probe_, "label", wire::ParamKind::kString, 0, 0.0, "second").type, msg::kOk);
  r = host().call_with(probe_, msg::kGetParam, name);
  ASSERT_EQ(r.type, msg::kParam);
  std::memcpy(&rec, r.body.data(), sizeof rec);
  EXPECT_STREQ(rec.string_value, "second");

  // Every parameter at once.
  r = host().call(probe_, msg::kGetParam);
  ASSERT_EQ(r.type, msg::kParam);
  ASSERT_EQ(r.body.size() % sizeof rec, 0u);
  EXPECT_EQ(r.body.size() / sizeof rec, 9u);  // Probe's 8 and the standard gdosLevel (first)
  std::memcpy(&rec, r.body.data(), sizeof rec);
  EXPECT_STREQ(rec.name, "gdosLevel");
  std::memcpy(&rec, r.body.data() + sizeof rec, sizeof rec);
  EXPECT_STREQ(rec.name, "fail_init");
}

TEST_F(LifecycleTest, ParamRequestsWithUnknownNameOrWrongTypeGetError) {
  Watchdog dog;
  start();
  wire::ParamName name;
  wire::copy_text(name.name, "no_such_param");
  auto r = host().call_with(probe_, msg::kGetParam, name);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("no_such_param"), std::string::npos) << r.error_text();

  r = host().set_param(probe_, "no_such_param", wire::ParamKind::kInt, 1);
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("no_such_param"), std::string::npos) << r.error_text();

  r = host().set_param(probe_, "fail_on", wire::ParamKind::kInt, 1);  // a bool
  EXPECT_EQ(r.type, msg::kError);
  EXPECT_NE(r.error_text().find("fail_on"), std::string::npos) << r.error_text();
  EXPECT_NE(r.error_text().find("type"), std::string::npos) << r.error_text();

  r = host().set_param(probe_, "on_delay_ms", wire::ParamKind::kInt, -1);  // below min 0
  EXPECT_EQ(r.type, msg::kError);

  r = host().set_param(probe_, "label", wire::ParamKind::kFloat, 0, 1.0);
  EXPECT_EQ(r.type, msg::kError);

  // Nothing was changed by the refused requests: ON still works.
  EXPECT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
}

TEST_F(LifecycleTest, MalformedRequestsGetErrorAndAreCounted) {
  Watchdog dog;
  start();
  const uint64_t before = host().stats(probe_).malformed;
  const uint64_t body8 = 0;
  const auto on = host().call(probe_, msg::kOn, &body8, sizeof body8);
  EXPECT_EQ(on.type, msg::kError);
  const char three[3] = {1, 2, 3};
  EXPECT_EQ(host().call(probe_, msg::kGetData, three, sizeof three).type, msg::kError);
  EXPECT_EQ(host().call(probe_, 99).type, msg::kError);
  EXPECT_EQ(host().stats(probe_).malformed, before + 3);
  // The ON with a body was not acted upon.
  EXPECT_EQ(host().status(probe_), msg::kDisabled);

  // More shapes of the same mistake.
  EXPECT_EQ(host().call(probe_, msg::kGetStatus, &body8, sizeof body8).type, msg::kError);
  EXPECT_EQ(host().call(probe_, msg::kOff, &body8, sizeof body8).type, msg::kError);
  EXPECT_EQ(host().call(probe_, msg::kGetContData, three, sizeof three).type, msg::kError);
  EXPECT_EQ(host().call(probe_, msg::kSetParam, three, sizeof three).type, msg::kError);
  EXPECT_EQ(host().call(probe_, interfaces::kProbeEcho, three, sizeof three).type, msg::kError);
  EXPECT_EQ(host().stats(probe_).malformed, before + 8);
  EXPECT_EQ(host().status(probe_), msg::kDisabled);
}

TEST_F(LifecycleTest, RequestToAnUnknownComponentIsAnsweredNotAvailable) {
  Watchdog dog;
  start();
  const auto r = host().call(Address::make(0, class_ids::kProbe, 9), msg::kGetStatus);
  ASSERT_EQ(r.status, CallStatus::kOk);
  EXPECT_EQ(r.type, msg::kNotAvailable);
}

TEST_F(LifecycleTest, StopSwitchesEverythingOff) {
  Watchdog dog;
  start("", 100, /*monitor=*/true, /*monitor_autostart=*/true);
  ASSERT_EQ(host().call(probe_, msg::kOn).type, msg::kOk);
  host().executor().stop();
  for (const auto& v : host().executor().components()) {
    EXPECT_EQ(v.component->state(), ComponentState::kDisabled) << v.component->name();
  }
  host().executor().stop();  // idempotent
}

}  // namespace
}  // namespace rack

namespace rack {
namespace {

// Every ERROR names its cause, through cascades: the ON answer and the GDOS error line
// of a consumer whose producer fails on(), and of one whose producer went OFF. Stepped
// (rack/core/stepper.h): each line is in the log once the request or step that made it
// has returned and the log is flushed.
TEST(ErrorReasonTest, ACascadeNamesTheProducerAndItsReason) {
  Watchdog dog;
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: probe
    class: Probe
    instance: 1
    retry_ms: 60000
    data_task: {period_ms: 10, ring: 64}
    params: {fail_on: true}
  - name: mon
    class: Monitor
    instance: 1
    retry_ms: 60000
    params: {source: probe, source_period_ms: 50, silence_ms: 1000}
)",
                           {}, /*capture_gdos=*/true, test::Stepping::kStepped);
  const Address mon = host.address_of("mon");
  const Address probe = host.address_of("probe");
  const auto gdos_log = [&] {
    host.executor().flush_log();
    return host.gdos_log();
  };
  const auto on = host.call(mon, msg::kOn);
  ASSERT_EQ(on.type, msg::kError);
  EXPECT_NE(on.error_text().find("on() failed: Probe(0/1) is in ERROR: on() failed"), std::string::npos)
      << on.error_text();
  EXPECT_NE(gdos_log().find("Probe(0/1) is in ERROR"), std::string::npos) << host.gdos_log();
  // GET_STATS (rackctl status) carries it while the ERROR lasts.
  EXPECT_NE(std::string(host.stats(mon).error_reason).find("Probe(0/1) is in ERROR"), std::string::npos)
      << host.stats(mon).error_reason;

  // The producer works again and goes OFF under its consumer: "left ENABLED".
  ASSERT_EQ(host.set_bool(probe, "fail_on", false).type, msg::kOk);
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  ASSERT_EQ(host.call(probe, msg::kOff).type, msg::kOk);
  EXPECT_TRUE(host.stepper().step("mon")) << "the monitor's data task takes the producer's ERROR";
  EXPECT_NE(gdos_log().find("ENABLED -> ERROR (Probe(0/1) left ENABLED"), std::string::npos) << host.gdos_log();
  EXPECT_NE(std::string(host.stats(mon).error_reason).find("left ENABLED"), std::string::npos);
  // ON (from ERROR, at once) switches the producer on again: no reason is shown any more.
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  EXPECT_STREQ(host.stats(mon).error_reason, "");
  // A parameter change is an info event.
  ASSERT_EQ(host.set_bool(probe, "fail_loop", false).type, msg::kOk);
  EXPECT_NE(gdos_log().find("SET_PARAM fail_loop = false"), std::string::npos) << host.gdos_log();
}

}  // namespace
}  // namespace rack
