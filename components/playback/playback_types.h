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

// Each playback class's PUBLISH: its body (the recorded time, then the sample of the
// class it plays back, under the type name <Class>PlaybackSample) and the command table
// its declaration names (k<Class>PlaybackBody, k<Class>PlaybackCommands).
#define RACK_PLAYBACK_COMMANDS(Class, Data, Fields)                                                        \
  inline constexpr DataTypeInfo k##Class##PlaybackBody = data_type_info<PlaybackSample<interfaces::Data>>( \
      #Class "PlaybackSample");                                                                            \
  inline constexpr CommandInfo k##Class##PlaybackCommands[] = {                                            \
      {"PUBLISH", kPlaybackPublish, &k##Class##PlaybackBody,                                               \
       "publish this sample (time_ns as recorded, then the " Fields " fields) as if the recorded producer had"}}

RACK_PLAYBACK_COMMANDS(Scan2d, Scan2dData, "Scan2D");
RACK_PLAYBACK_COMMANDS(Ladar, LadarData, "Ladar");
RACK_PLAYBACK_COMMANDS(Odometry, OdometryData, "Odometry");
RACK_PLAYBACK_COMMANDS(Chassis, ChassisData, "Chassis");
RACK_PLAYBACK_COMMANDS(Position, PositionData, "Position");
RACK_PLAYBACK_COMMANDS(Mcl, MclData, "MCL");
RACK_PLAYBACK_COMMANDS(Path, PathData, "Path");
RACK_PLAYBACK_COMMANDS(ServoDrive, ServoDriveData, "ServoDrive");
RACK_PLAYBACK_COMMANDS(Generator, GeneratorData, "Generator");

#undef RACK_PLAYBACK_COMMANDS

}  // namespace rack::components
