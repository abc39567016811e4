// Odometry (class Odometry): integrates a Chassis' increments into a pose in the
// odometry frame. Triggered by the chassis' samples (getContData, cascading ON);
// each sample is published with the chassis sample's time, so the ring answers
// getData(t) with the odometry at the moment the wheels were read (Position and
// Scan2D look it up by time). RESET zeroes the pose from the next chassis sample on.
//
// Real-time contract: on(), off(), loop() and command() are RT-safe.
#pragma once

#include <cstdint>

#include "common/pose2d.h"
#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Odometry final : public DataComponent<interfaces::OdometryData> {
 public:
  Odometry();

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, triggered by ChassisData
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  InputOf<interfaces::ChassisData>& chassis_;
  interfaces::OdometryData odo_{};
  Handoff<uint32_t> resets_;  // RESETs asked for (command task), applied by the data task
};

}  // namespace rack::components
