// The playback classes' command (PUBLISH) and its body, declared apart from the
// component (components/playback/playback.h) so that the class tables that tools
// link can include it without the executor.
//
// Real-time contract: constant data and a trivially copyable struct.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/interfaces/robot.h"
#include "rack/tims/payload.h"

namespace rack::components {

inline constexpr int8_t kPlaybackPublish = 21;

// PUBLISH's body: the sample's time and the sample (T's fields, by their names).
template <tims::Payload T>
struct PlaybackSample {
  int64_t time_ns = 0;
  T data{};
  static constexpr auto fields() noexcept {
    constexpr auto inner = tims::fields_of<T>;
    std::array<tims::FieldDesc, inner.size() + 1> out{};
    out[0] = RACK_FIELD(PlaybackSample, time_ns);
    for (std::size_t i = 0; i < inner.size(); ++i) {
      out[i + 1] = inner[i];
      out[i + 1].offset += static_cast<uint32_t>(offsetof(PlaybackSample, data));
    }
    return out;
  }
};

inline constexpr DataTypeInfo kScan2dPlaybackBody = data_type_info<PlaybackSample<interfaces::Scan2dData>>(
    "Scan2dPlaybackSample");
inline constexpr CommandInfo kScan2dPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kScan2dPlaybackBody,
     "publish this sample (time_ns as recorded, then the Scan2D fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kLadarPlaybackBody = data_type_info<PlaybackSample<interfaces::LadarData>>(
    "LadarPlaybackSample");
inline constexpr CommandInfo kLadarPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kLadarPlaybackBody,
     "publish this sample (time_ns as recorded, then the Ladar fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kOdometryPlaybackBody = data_type_info<PlaybackSample<interfaces::OdometryData>>(
    "OdometryPlaybackSample");
inline constexpr CommandInfo kOdometryPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kOdometryPlaybackBody,
     "publish this sample (time_ns as recorded, then the Odometry fields) as if the recorded producer had"}};

}  // namespace rack::components
