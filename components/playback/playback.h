// Playback classes: a component that publishes the samples a tool sends it, in place
// of the producer that recorded them, so that the consumers of a host (MCL, Pilot, a
// trajectory writer) receive a recording as they would the live data. rack-foxglove's
// player (tools/foxglove, `rack-foxglove play`) reads an MCAP recording and sends each
// recorded sample, at the recorded speed or faster, as a PUBLISH command through
// rack-gui; the host file names the playback class where the recorded one was:
//
//   - name: scan2d
//     class: Scan2dPlayback        # in place of Scan2D: MCL's `scan2d: scan2d` finds it
//     instance: 0
//     autostart: true
//     data_task: {period_ms: 100, ring: 25}
//
// PUBLISH (type 21) carries the sample's time (ns, as recorded) and the sample itself
// (the class's data type, field by field): PlaybackSample<T>. The component publishes it
// at once with that time, from its command task; the data task does nothing. A PUBLISH
// while the component is not ENABLED is refused (ERROR), one whose time is not after the
// previous sample's or whose body has the wrong size is rejected as malformed and
// counted (GET_STATS), and the component keeps running.
//
// Classes:
//   - Scan2dPlayback (Scan2D: what MCL localises on; the scans carry the odometry at
//     their time, so no Odometry or Chassis is needed beside them);
//   - LadarPlayback and OdometryPlayback (Ladar, Odometry): the sensor and the motion
//     as recorded at their full rate, so that a live Scan2D builds the scans (holding
//     each until the played odometry at its time has come) and MCL runs its motion
//     model on the recorded odometry (configs/replay_mcap_mcl.yaml);
//   - ChassisPlayback (Chassis: an Odometry integrates its increments, as the CARMEN
//     replay's ChassisReplay feeds it), PositionPlayback (Position: the Pilot, Scan3D
//     and the evaluators take it), MclPlayback (MCL: the evaluators and the trajectory
//     writer), PathPlayback (Path: the Pilot), ServoDrivePlayback (ServoDrive: Scan3D,
//     LadarSim) and GeneratorPlayback (Generator: the Monitor): every class whose data
//     a component of the tree takes as an input (its declare_input), so that any
//     recorded stream plays into a host. Not Camera: its samples (0.9 MB) are not
//     streamed to a recorder (larger than rack-gui's stream slots).
//
// Real-time contract: command() is RT-safe (the sample is copied into a member; no
// allocation); loop() does nothing.
#pragma once

#include "playback_types.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/demo.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

template <tims::Payload T>
class Playback : public DataComponent<T> {
 public:
  Playback() : DataComponent<T>(DataTaskMode::kPeriodic) {
    this->set_command_slot_size(static_cast<uint32_t>(sizeof(tims::MessageHeader) + sizeof(PlaybackSample<T>) + 64));
  }

 protected:
  HookResult on() override {
    last_time_ns_ = 0;
    return HookResult::kOk;
  }
  HookResult loop() override { return HookResult::kOk; }
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override {
    if (request.type != kPlaybackPublish) return CommandResult::kUnknown;
    if (!wire::read_payload(body, tims::body_is_native(request), sample_)) {
      this->reject_malformed(request, "PUBLISH: body must be the time (i64) and one sample of the class's data type");
      return CommandResult::kHandled;
    }
    if (sample_.time_ns <= last_time_ns_) {
      this->reject_malformed(request, "PUBLISH: time_ns must be after the previous sample's");
      return CommandResult::kHandled;
    }
    if (this->state() != ComponentState::kEnabled) {
      this->reply_error(request, "PUBLISH: not enabled");
      return CommandResult::kHandled;
    }
    last_time_ns_ = sample_.time_ns;
    this->publish(sample_.data, sample_.time_ns);
    this->reply(request, tims::msg::kOk);
    return CommandResult::kHandled;
  }

 private:
  PlaybackSample<T> sample_{};  // command task only
  int64_t last_time_ns_ = 0;    // command task only
};

class Scan2dPlayback final : public Playback<interfaces::Scan2dData> {};
class LadarPlayback final : public Playback<interfaces::LadarData> {};
class OdometryPlayback final : public Playback<interfaces::OdometryData> {};
class ChassisPlayback final : public Playback<interfaces::ChassisData> {};
class PositionPlayback final : public Playback<interfaces::PositionData> {};
class MclPlayback final : public Playback<interfaces::MclData> {};
class PathPlayback final : public Playback<interfaces::PathData> {};
class ServoDrivePlayback final : public Playback<interfaces::ServoDriveData> {};
class GeneratorPlayback final : public Playback<interfaces::GeneratorData> {};

}  // namespace rack::components
