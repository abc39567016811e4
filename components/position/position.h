// Position (class Position): the robot's pose in the map frame = the reference pose
// composed with the odometry travelled since the reference's time.
//
// The reference starts as the `initial_*` parameters at the first odometry sample
// after the first ON; a later ON continues from the last published pose (the robot
// did not jump back to its start because a component was restarted). UPDATE (e.g. from MCL, for a scan taken a while ago) re-anchors it: the
// command task looks up the Odometry's sample AT THE UPDATE'S TIME (GET_DATA by
// time), advances it by that sample's velocities to the exact time, and from then on
// pose = update (+) (odometry(update time)^-1 (+) odometry(now)). Motion after the
// update's time is therefore kept, not lost. Triggered by the Odometry's samples and
// published with their time.
//
// An odometry RESET re-anchors at the current pose; an UPDATE for a time before the
// last RESET is refused (its odometry frame is gone).
//
// Threads: the command task (UPDATE) hands the new reference to the data task (a
// Handoff), which applies it at the next odometry sample. Real-time contract: on(),
// off(), loop() and command() are RT-safe.
#pragma once

#include <atomic>

#include "common/pose2d.h"
#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Position final : public DataComponent<interfaces::PositionData> {
 public:
  Position();

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, triggered by OdometryData
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  struct Reference {
    Pose2d pose;            // map frame, at `time_ns`
    Pose2d odometry;        // odometry frame, at `time_ns`
    double distance = 0.0;  // odometry path length at `time_ns`
    double var_x = 0.0, var_y = 0.0, var_phi = 0.0;
    int64_t time_ns = 0;  // 0: not anchored yet (anchors at the first sample)
    uint32_t resets = 0;  // the odometry's RESET count the reference belongs to
    uint32_t updates = 0;
  };
  void handle_update(const tims::MessageHeader& request, std::span<const std::byte> body) noexcept;

  InputOf<interfaces::OdometryData>& odometry_;
  Parameter& initial_x_;
  Parameter& initial_y_;
  Parameter& initial_phi_;
  Parameter& initial_var_xy_;
  Parameter& initial_var_phi_;
  Parameter& var_xy_per_m_;
  Parameter& var_phi_per_m_;

  Handoff<Reference> update_;  // UPDATE (command task) -> the data task
  Reference reference_;        // data task (on() sets it while the data task is idle)
  // The odometry's RESET count in its newest sample (data task writes; the command
  // task refuses UPDATEs from an older frame). Relaxed: a one-sample lag is harmless.
  std::atomic<uint32_t> odometry_resets_{0};
  interfaces::PositionData last_{};  // data task (on() reads it while the data task is idle)
  bool published_ = false;           // a pose was published since init(): later ONs continue from it
};

}  // namespace rack::components
