// Odometry (class Odometry): integrates a Chassis' increments into a pose in the
// odometry frame. Triggered by the chassis' samples (getContData, cascading ON);
// each sample is published with the chassis sample's time, so the ring answers
// getData(t) with the odometry at the moment the wheels were read (Position and
// Scan2D look it up by time). RESET zeroes the pose from the next chassis sample on.
//
// Real-time contract: on(), off(), loop() and command() are RT-safe.
#pragma once

#include <atomic>

#include "common/pose2d.h"
#include "rack/core/data_component.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Odometry final : public DataComponent<interfaces::OdometryData> {
 public:
  Odometry();

 protected:
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT, triggered by ChassisData
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  Parameter& chassis_;
  interfaces::OdometryData odo_{};
  // RESETs asked for by the command task, applied by the data task (relaxed counter:
  // the data task compares it with what it applied; the pose itself is its own).
  std::atomic<uint32_t> reset_requests_{0};
  uint32_t resets_applied_ = 0;
};

}  // namespace rack::components
