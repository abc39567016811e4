// Scan2dPlayback (components/playback) in a real executor: a PUBLISH is published at
// once with its recorded time and fields; a PUBLISH of the wrong size, with a time not
// after the previous one's, or while the component is OFF is refused, the malformed
// ones counted, and the component keeps publishing.
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <string>

#include "playback/playback.h"
#include "test_support.h"

namespace rack::test {
namespace {

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

}  // namespace
}  // namespace rack::test
