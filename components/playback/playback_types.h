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
#include "rack/interfaces/demo.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/navigation.h"
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
    constexpr auto kInner = tims::fields_of<T>;
    std::array<tims::FieldDesc, kInner.size() + 1> out{};
    out[0] = RACK_FIELD(PlaybackSample, time_ns);
    for (std::size_t i = 0; i < kInner.size(); ++i) {
      out[i + 1] = kInner[i];
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

inline constexpr DataTypeInfo kChassisPlaybackBody = data_type_info<PlaybackSample<interfaces::ChassisData>>(
    "ChassisPlaybackSample");
inline constexpr CommandInfo kChassisPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kChassisPlaybackBody,
     "publish this sample (time_ns as recorded, then the Chassis fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kPositionPlaybackBody = data_type_info<PlaybackSample<interfaces::PositionData>>(
    "PositionPlaybackSample");
inline constexpr CommandInfo kPositionPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kPositionPlaybackBody,
     "publish this sample (time_ns as recorded, then the Position fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kMclPlaybackBody = data_type_info<PlaybackSample<interfaces::MclData>>(
    "MclPlaybackSample");
inline constexpr CommandInfo kMclPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kMclPlaybackBody,
     "publish this sample (time_ns as recorded, then the MCL fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kPathPlaybackBody = data_type_info<PlaybackSample<interfaces::PathData>>(
    "PathPlaybackSample");
inline constexpr CommandInfo kPathPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kPathPlaybackBody,
     "publish this sample (time_ns as recorded, then the Path fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kServoDrivePlaybackBody = data_type_info<PlaybackSample<interfaces::ServoDriveData>>(
    "ServoDrivePlaybackSample");
inline constexpr CommandInfo kServoDrivePlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kServoDrivePlaybackBody,
     "publish this sample (time_ns as recorded, then the ServoDrive fields) as if the recorded producer had"}};

inline constexpr DataTypeInfo kGeneratorPlaybackBody = data_type_info<PlaybackSample<interfaces::GeneratorData>>(
    "GeneratorPlaybackSample");
inline constexpr CommandInfo kGeneratorPlaybackCommands[] = {
    {"PUBLISH", kPlaybackPublish, &kGeneratorPlaybackBody,
     "publish this sample (time_ns as recorded, then the Generator fields) as if the recorded producer had"}};

}  // namespace rack::components
