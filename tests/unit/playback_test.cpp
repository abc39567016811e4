// Scan2dPlayback (components/playback) in a real executor: a PUBLISH is published at
// once with its recorded time and fields; a PUBLISH of the wrong size, with a time not
// after the previous one's, or while the component is OFF is refused, the malformed
// ones counted, and the component keeps publishing. LadarPlayback and OdometryPlayback
// feed a live Scan2D, which builds the scan with the played odometry at its time.
// Every other playback class (Chassis, Position, MCL, Path, ServoDrive, Generator)
// publishes what it is sent, fields and time as sent.
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <string>

#include "playback/playback.h"
#include "test_support.h"

namespace rack::test {
namespace {

using interfaces::LadarData;
using interfaces::OdometryData;
using interfaces::Scan2dData;
namespace msg = tims::msg;

const char* kHost = R"(host: playback-test
system: 0
components:
  - name: scan2d
    class: Scan2dPlayback
    instance: 0
    data_task: {period_ms: 100, ring: 8}
)";

TEST(PlaybackTest, PublishesWhatItIsSentWithTheRecordedTimeAndRefusesTheRest) {
  Watchdog dog;
  HostUnderTest host(kHost);
  const tims::Address a = host.address_of("scan2d");
  auto body = std::make_unique<components::PlaybackSample<Scan2dData>>();
  body->time_ns = 1'795'652'163'482'672'640;
  body->data.point_count = 3;
  body->data.odometry_valid = 1;
  body->data.odometry_x = 6.25;
  body->data.x[2] = 1.5F;
  body->data.range[2] = 2.5F;

  // OFF: refused, not counted as malformed.
  const auto off = host.call_with(a, components::kPlaybackPublish, *body);
  EXPECT_EQ(off.type, msg::kError);
  EXPECT_NE(off.error_text().find("not enabled"), std::string::npos) << off.error_text();

  ASSERT_EQ(host.call(a, msg::kOn).type, msg::kOk);
  ASSERT_EQ(host.call_with(a, components::kPlaybackPublish, *body).type, msg::kOk);
  const auto got = host.call(a, msg::kGetData);
  ASSERT_EQ(got.type, msg::kData);
  ASSERT_EQ(got.body.size(), sizeof(wire::SampleHeader) + sizeof(Scan2dData));
  wire::SampleHeader sh;
  auto sample = std::make_unique<Scan2dData>();
  std::memcpy(&sh, got.body.data(), sizeof sh);
  std::memcpy(sample.get(), got.body.data() + sizeof sh, sizeof *sample);
  EXPECT_EQ(sh.time_ns, body->time_ns);
  EXPECT_EQ(sample->point_count, 3u);
  EXPECT_EQ(sample->odometry_x, 6.25);
  EXPECT_EQ(sample->x[2], 1.5F);
  EXPECT_EQ(sample->range[2], 2.5F);

  // The same time again, and a body cut short: malformed, counted.
  const auto again = host.call_with(a, components::kPlaybackPublish, *body);
  EXPECT_EQ(again.type, msg::kError);
  EXPECT_NE(again.error_text().find("after the previous"), std::string::npos) << again.error_text();
  const auto cut = host.call(a, components::kPlaybackPublish, body.get(), sizeof *body - 8);
  EXPECT_EQ(cut.type, msg::kError);
  EXPECT_NE(cut.error_text().find("body must be"), std::string::npos) << cut.error_text();
  EXPECT_EQ(host.stats(a).malformed, 2u);

  // It goes on: a later sample is published.
  body->time_ns += 40'000'000;
  ASSERT_EQ(host.call_with(a, components::kPlaybackPublish, *body).type, msg::kOk);
  EXPECT_EQ(host.status(a), msg::kEnabled);
  const auto next = host.call(a, msg::kGetData);
  ASSERT_EQ(next.type, msg::kData);
  std::memcpy(&sh, next.body.data(), sizeof sh);
  EXPECT_EQ(sh.time_ns, body->time_ns);
}

const char* kPipeline = R"(host: playback-pipeline-test
system: 0
lcm: false
components:
  - name: ladar
    class: LadarPlayback
    instance: 0
    data_task: {period_ms: 40, ring: 8}
  - name: odometry
    class: OdometryPlayback
    instance: 0
    data_task: {period_ms: 10, ring: 64}
  - name: scan2d
    class: Scan2D
    instance: 0
    data_task: {timeout_ms: 2000, ring: 8}
    params:
      ladar: ladar
      odometry: odometry
)";

TEST(PlaybackTest, LadarAndOdometryPlaybackFeedALiveScan2dWithTheOdometryAtTheScansTime) {
  Watchdog dog;
  // Stepped (rack/core/stepper.h): requests are answered when sent, and waiting for the
  // scan moves the virtual clock to the first instant it is there.
  HostUnderTest host(kPipeline, {}, false, test::Stepping::kStepped);
  const tims::Address ladar = host.address_of("ladar");
  const tims::Address odometry = host.address_of("odometry");
  const tims::Address scan2d = host.address_of("scan2d");
  ASSERT_EQ(host.call(scan2d, msg::kOn).type, msg::kOk);  // cascading ON: both playbacks
  ASSERT_EQ(host.status(ladar), msg::kEnabled);
  ASSERT_EQ(host.status(odometry), msg::kEnabled);

  const int64_t t0 = 1'795'652'163'000'000'000;
  components::PlaybackSample<OdometryData> odo;
  odo.time_ns = t0;
  odo.data.x = 1.0;
  ASSERT_EQ(host.call_with(odometry, components::kPlaybackPublish, odo).type, msg::kOk);
  // The scan 20 ms later: Scan2D holds it until odometry at or after its time comes.
  auto scan = std::make_unique<components::PlaybackSample<LadarData>>();
  scan->time_ns = t0 + 20'000'000;
  scan->data.max_range = 20.0F;
  scan->data.start_angle = -0.5F;
  scan->data.angle_step = 0.5F;
  scan->data.beam_count = 3;
  scan->data.range[0] = scan->data.range[1] = scan->data.range[2] = 2.0F;
  ASSERT_EQ(host.call_with(ladar, components::kPlaybackPublish, *scan).type, msg::kOk);
  odo.time_ns = t0 + 40'000'000;
  odo.data.x = 3.0;
  odo.data.phi = 0.2;
  ASSERT_EQ(host.call_with(odometry, components::kPlaybackPublish, odo).type, msg::kOk);

  wire::SampleHeader sh;
  auto out = std::make_unique<Scan2dData>();
  ASSERT_TRUE(host.stepper().run_until([&] { return host.get_data(scan2d, sh, *out) && sh.time_ns == scan->time_ns; },
                                       10 * rt::kNsPerSec))
      << "no scan at the played time";
  EXPECT_EQ(out->odometry_valid, 1u);
  EXPECT_NEAR(out->odometry_x, 2.0, 1e-9);  // halfway between the two played poses
  EXPECT_NEAR(out->odometry_phi, 0.1, 1e-9);
  EXPECT_EQ(out->point_count, 3u);
}

const char* kEveryClass = R"(host: playback-classes-test
system: 0
components:
  - {name: chassis, class: ChassisPlayback, instance: 0, data_task: {period_ms: 100, ring: 8}}
  - {name: position, class: PositionPlayback, instance: 0, data_task: {period_ms: 100, ring: 8}}
  - {name: mcl, class: MclPlayback, instance: 0, data_task: {period_ms: 100, ring: 8}}
  - {name: path, class: PathPlayback, instance: 0, data_task: {period_ms: 100, ring: 4}}
  - {name: servo, class: ServoDrivePlayback, instance: 0, data_task: {period_ms: 100, ring: 8}}
  - {name: generator, class: GeneratorPlayback, instance: 0, data_task: {period_ms: 100, ring: 8}}
)";

// One PUBLISH of `sample` into the playback component `name` (switched on first): the
// sample it then gives (GET_DATA) is the one sent, at the time sent, byte for byte.
template <typename T>
void expect_played(HostUnderTest& host, const char* name, const T& sample, int64_t time_ns) {
  SCOPED_TRACE(name);
  const tims::Address a = host.address_of(name);
  ASSERT_EQ(host.call(a, msg::kOn).type, msg::kOk);
  auto body = std::make_unique<components::PlaybackSample<T>>();
  body->time_ns = time_ns;
  body->data = sample;
  ASSERT_EQ(host.call_with(a, components::kPlaybackPublish, *body).type, msg::kOk);
  wire::SampleHeader sh;
  auto got = std::make_unique<T>();
  ASSERT_TRUE(host.get_data(a, sh, *got));
  EXPECT_EQ(sh.time_ns, time_ns);
  EXPECT_EQ(std::memcmp(got.get(), &sample, sizeof(T)), 0) << "the published sample differs from the one sent";
}

TEST(PlaybackTest, EveryInputClassHasAPlaybackThatPublishesWhatItIsSent) {
  Watchdog dog;
  HostUnderTest host(kEveryClass);
  const int64_t t = 1'795'652'163'482'672'641;  // odd: the exact time, not a rounded one
  interfaces::ChassisData chassis{};
  chassis.delta_x = 0.004;
  chassis.vx = 0.4;
  chassis.truth_valid = 1;
  chassis.truth_x = 4.5;
  expect_played(host, "chassis", chassis, t);
  interfaces::PositionData position{};
  position.x = 4.25;
  position.phi = -0.5;
  position.reference_time_ns = t - 1;
  position.updates = 7;
  expect_played(host, "position", position, t + 1);
  auto mcl = std::make_unique<interfaces::MclData>();
  mcl->x = 12.5;
  mcl->scan_time_ns = t - 3;
  mcl->shown = 2;
  mcl->particle_x[1] = 1.5F;
  mcl->particle_weight[1] = 0.5F;
  expect_played(host, "mcl", *mcl, t + 2);
  auto path = std::make_unique<interfaces::PathData>();
  path->point_count = 3;
  path->x[2] = 20.0F;
  path->y[2] = 7.5F;
  path->last_error[0] = 'x';
  expect_played(host, "path", *path, t + 3);
  interfaces::ServoDriveData servo{};
  servo.position = 0.75;
  expect_played(host, "servo", servo, t + 4);
  interfaces::GeneratorData generator{};
  generator.value = -2.5;
  generator.counter = 41;
  expect_played(host, "generator", generator, t + 5);
}

}  // namespace
}  // namespace rack::test
