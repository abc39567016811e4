// The stepping executor and its virtual clock (rack/core/stepper.h, rack/rt/clock.h):
// no task threads, requests answered when sent, data tasks stepped at exact virtual
// times, and the time-based behaviour (periods, silence, the back-off in ERROR)
// following the virtual clock to the nanosecond.
#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>

#include "rack/core/stepper.h"
#include "monitor/monitor_types.h"
#include "rack/interfaces/demo.h"
#include "test_support.h"

namespace rack {
namespace {

using interfaces::GeneratorData;
using interfaces::MonitorData;
using test::generator_monitor_yaml;
using test::HostUnderTest;
using test::Stepping;
using test::Watchdog;
using tims::Address;
namespace msg = tims::msg;
constexpr int64_t kMs = rt::kNsPerMs;

TEST(VirtualClockTest, ClockReadsAndSleepsFollowItWhileItIsInstalled) {
  EXPECT_EQ(rt::virtual_clock(), nullptr);
  {
    rt::VirtualClock clock(5 * rt::kNsPerSec, 100 * rt::kNsPerSec);
    EXPECT_EQ(rt::virtual_clock(), &clock);
    EXPECT_EQ(rt::monotonic_ns(), 5 * rt::kNsPerSec);
    EXPECT_EQ(rt::host_time_ns(), 100 * rt::kNsPerSec);
    EXPECT_EQ(clock.advance(7), 5 * rt::kNsPerSec + 7);
    EXPECT_EQ(rt::monotonic_ns(), 5 * rt::kNsPerSec + 7);
    EXPECT_EQ(rt::host_time_ns(), 100 * rt::kNsPerSec + 7);
    // Sleeping is time passing (one thread steps), and it never goes back.
    rt::sleep_for(3 * kMs);
    EXPECT_EQ(rt::monotonic_ns(), 5 * rt::kNsPerSec + 7 + 3 * kMs);
    rt::sleep_until_monotonic(rt::kNsPerSec);
    EXPECT_EQ(rt::monotonic_ns(), 5 * rt::kNsPerSec + 7 + 3 * kMs);
    EXPECT_EQ(clock.advance_to(rt::kNsPerSec), 5 * rt::kNsPerSec + 7 + 3 * kMs);
    EXPECT_EQ(clock.advance(-5), 5 * rt::kNsPerSec + 7 + 3 * kMs);
    // The kernel's clock is not virtual: waits that the kernel times use it.
    EXPECT_GT(rt::os_monotonic_ns(), 0);
    EXPECT_NE(rt::os_monotonic_ns(), rt::monotonic_ns());
    EXPECT_THROW(rt::VirtualClock second, std::logic_error) << "one virtual clock at a time";
  }
  EXPECT_EQ(rt::virtual_clock(), nullptr);
  const int64_t a = rt::monotonic_ns();
  EXPECT_GE(rt::os_monotonic_ns(), a);
}

// Only the stepping thread's sleeps are time passing. Another thread's (LCM's, an I/O
// worker's) sleeps as long on the kernel's clock and leaves the virtual one alone:
// LcmTransport's maintenance loop, rt::sleep_for(50 ms) a turn, used to move it at
// full speed (minutes of virtual time in PlaybackTest's 51 ms on CI).
TEST(VirtualClockTest, AnotherThreadsSleepWaitsOnTheKernelsClockAndMovesNothing) {
  Watchdog dog;
  rt::VirtualClock clock(5 * rt::kNsPerSec, 100 * rt::kNsPerSec);
  int64_t seen = 0;
  int64_t slept_ns = 0;
  std::thread other([&] {
    const int64_t before = rt::os_monotonic_ns();
    rt::sleep_for(3 * kMs);
    rt::sleep_until_monotonic(5 * rt::kNsPerSec + 2 * kMs);  // 2 ms of virtual time ahead
    rt::sleep_until_monotonic(rt::kNsPerSec);                // past: no wait
    slept_ns = rt::os_monotonic_ns() - before;
    seen = rt::monotonic_ns();
  });
  other.join();
  EXPECT_EQ(clock.now_ns(), 5 * rt::kNsPerSec) << "another thread's sleep moved the virtual clock";
  EXPECT_EQ(seen, 5 * rt::kNsPerSec);
  EXPECT_GE(slept_ns, 5 * kMs) << "it did not sleep on the kernel's clock as long as asked";
  rt::sleep_for(3 * kMs);  // the installing thread's sleep still is time passing
  EXPECT_EQ(clock.now_ns(), 5 * rt::kNsPerSec + 3 * kMs);
}

// A stepped executor runs without LCM: its transport's threads would serve messages
// beside the stepping thread (and move the clock, see above).
TEST(StepperTest, ASteppedExecutorRefusesAHostWithLcm) {
  Watchdog dog;
  const std::string yaml = R"(system: 0
components:
  - {name: gen, class: Generator, instance: 1, data_task: {period_ms: 10, ring: 8}}
)";
  try {
    HostUnderTest host(yaml, {}, false, Stepping::kStepped);
    ADD_FAILURE() << "a stepped executor started with LCM on";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("lcm: false"), std::string::npos) << e.what();
  }
  EXPECT_EQ(rt::virtual_clock(), nullptr);
}

TEST(StepperTest, RequestsAreAnsweredAtOnceWithoutTaskThreads) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml(), {}, false, Stepping::kStepped);
  const int64_t t0 = host.stepper().now_ns();
  const Address gen = host.address_of("gen");
  const Address mon = host.address_of("mon");
  // ON of the monitor: its cascading ON of the generator and its subscription run
  // inside this call (each request served in the sender's thread), with no time passing.
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  EXPECT_EQ(host.status(gen), msg::kEnabled);
  EXPECT_EQ(host.stats(gen).listeners, 1u);
  EXPECT_EQ(host.stepper().now_ns(), t0);
  EXPECT_EQ(host.stats(gen).data.cycles, 0u) << "no data task ran by itself";
  EXPECT_THROW((void)host.stepper().step("nobody"), std::invalid_argument);
}

TEST(StepperTest, APeriodicTaskRunsOneCycleAtEachDeadline) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml(), {}, false, Stepping::kStepped);
  Stepper& s = host.stepper();
  const Address gen = host.address_of("gen");
  ASSERT_EQ(host.call(gen, msg::kOn).type, msg::kOk);
  // The first deadline is one period after start().
  EXPECT_FALSE(s.step("gen"));
  s.advance(10 * kMs - 1);
  EXPECT_FALSE(s.step("gen")) << "1 ns before the deadline";
  s.advance(1);
  EXPECT_TRUE(s.step("gen"));
  EXPECT_FALSE(s.step("gen")) << "one cycle per deadline";
  wire::SampleHeader sh;
  GeneratorData d;
  ASSERT_TRUE(host.get_data(gen, sh, d));
  EXPECT_EQ(d.counter, 1);
  EXPECT_EQ(sh.time_ns, host.clock().host_ns()) << "sample times are the virtual host clock's";
  // 100 ms more: exactly 10 more cycles, none overrun.
  EXPECT_EQ(s.run_for(100 * kMs), 10u);
  ASSERT_TRUE(host.get_data(gen, sh, d));
  EXPECT_EQ(d.counter, 11);
  EXPECT_EQ(host.stats(gen).data.cycles, 11u);
  EXPECT_EQ(host.stats(gen).data.overruns, 0u);
  // A jump over several deadlines is one late cycle and counted overruns, as a stalled
  // thread's would be (no burst to catch up).
  s.advance(35 * kMs);
  EXPECT_TRUE(s.step("gen"));
  EXPECT_FALSE(s.step("gen"));
  EXPECT_EQ(host.stats(gen).data.overruns, 2u) << "the deadlines at +10 and +20 ms of the 25 ms late one";
}

TEST(StepperTest, ATriggeredTaskRunsWhenASampleWaits) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml(), {}, false, Stepping::kStepped);
  Stepper& s = host.stepper();
  const Address mon = host.address_of("mon");
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  EXPECT_FALSE(s.step("mon")) << "nothing waits";
  s.advance(10 * kMs);
  EXPECT_FALSE(s.step("mon")) << "the generator has not run: still nothing";
  EXPECT_TRUE(s.step("gen"));
  EXPECT_TRUE(s.step("mon")) << "the generator's sample waits";
  EXPECT_FALSE(s.step("mon"));
  wire::SampleHeader sh;
  MonitorData d;
  ASSERT_TRUE(host.get_data(mon, sh, d));
  EXPECT_EQ(d.received, 1u);
  EXPECT_EQ(d.latency_ns, 0) << "no time passed between the generator's cycle and the monitor's";
  // run_for steps the consumer at the producer's instant: 50 ms, 5 samples.
  (void)s.run_for(50 * kMs);
  ASSERT_TRUE(host.get_data(mon, sh, d));
  EXPECT_EQ(d.received, 6u);
  EXPECT_EQ(d.gaps, 0u);
  EXPECT_EQ(sh.time_ns, host.clock().host_ns());
}

TEST(StepperTest, SilenceIsNoticedExactlyAfterSilenceMs) {
  Watchdog dog;
  // One sample every 1.5 s asked of the source, silence after 200 ms.
  HostUnderTest host(generator_monitor_yaml(", source_period_ms: 1500, silence_ms: 200", 60000), {}, false,
                     Stepping::kStepped);
  Stepper& s = host.stepper();
  const Address mon = host.address_of("mon");
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  (void)s.run_for(200 * kMs - 1);
  EXPECT_EQ(host.status(mon), msg::kEnabled) << "1 ns before silence_ms";
  (void)s.run_for(1);
  EXPECT_EQ(host.status(mon), msg::kError);
  const std::string reason = host.stats(mon).error_reason;
  EXPECT_NE(reason.find("sent nothing for 200 ms (silence_ms 200)"), std::string::npos) << reason;
}

TEST(StepperTest, TheRetryInErrorComesExactlyAfterRetryMs) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml("", 100), {}, false, Stepping::kStepped);
  Stepper& s = host.stepper();
  const Address gen = host.address_of("gen");
  const Address mon = host.address_of("mon");
  ASSERT_EQ(host.call(mon, msg::kOn).type, msg::kOk);
  (void)s.run_for(30 * kMs);
  // The source goes away: the monitor takes the ERROR at the instant it comes.
  ASSERT_EQ(host.call(gen, msg::kOff).type, msg::kOk);
  EXPECT_EQ(host.status(mon), msg::kEnabled) << "its data task has not run yet";
  EXPECT_TRUE(s.step("mon"));
  EXPECT_EQ(host.status(mon), msg::kError);
  EXPECT_NE(std::string(host.stats(mon).error_reason).find("left ENABLED"), std::string::npos);
  // The retry (every retry_ms) switches the source on again and subscribes again.
  (void)s.run_for(100 * kMs - 1);
  EXPECT_EQ(host.status(mon), msg::kError) << "1 ns before the back-off";
  (void)s.run_for(1);
  EXPECT_EQ(host.status(mon), msg::kEnabled);
  EXPECT_EQ(host.status(gen), msg::kEnabled);
  EXPECT_EQ(host.stats(gen).listeners, 1u);
}

TEST(StepperTest, RunUntilStopsAtTheFirstInstantThePredicateHolds) {
  Watchdog dog;
  HostUnderTest host(generator_monitor_yaml(), {}, false, Stepping::kStepped);
  Stepper& s = host.stepper();
  const Address gen = host.address_of("gen");
  const int64_t t0 = s.now_ns();
  ASSERT_EQ(host.call(gen, msg::kOn).type, msg::kOk);
  GeneratorData d;
  wire::SampleHeader sh;
  EXPECT_TRUE(s.run_until([&] { return host.get_data(gen, sh, d) && d.counter == 25; }, rt::kNsPerSec));
  EXPECT_EQ(s.now_ns() - t0, 250 * kMs);
  EXPECT_FALSE(s.run_until([] { return false; }, 40 * kMs));
  EXPECT_EQ(s.now_ns() - t0, 290 * kMs);
}

TEST(StepperTest, AStepperNeedsASteppedExecutor) {
  Watchdog dog;
  HostUnderTest threaded(generator_monitor_yaml());
  EXPECT_THROW(Stepper{threaded.executor()}, std::logic_error);
}

}  // namespace
}  // namespace rack
