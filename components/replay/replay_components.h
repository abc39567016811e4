// Replay drivers: a recorded log (CARMEN or MRPT rawlog) played back as a Chassis and
// a Ladar, at the recorded speed or faster, so that the rest of the pipeline is the
// same as on the robot or in simulation:
//
//   ChassisReplay (Chassis) -> Odometry -> Scan2D <- LadarReplay (Ladar)  -> MCL
//
// ChassisReplay publishes ChassisData increments (the motion between consecutive
// odometry poses of the log, in the earlier pose's frame), exactly what a real
// chassis or ChassisSim publishes; the Odometry component integrates them as usual,
// and Scan2D looks up the odometry at each scan's time. Publishing OdometryData
// directly would bypass Odometry (its RESET, its history for Position UPDATE).
//
// Both components that name the same file share its replay clock (one per file and
// process): log time t plays at host time anchor + (t - t_first) / speed, the anchor
// being when the first of them was switched on, so scans and odometry stay in step.
// A component switched on within 2 s of that plays from the log's beginning; one
// switched on later (or again) joins the running clock and skips what has played.
// At the end of the log both stop publishing. Sample times are the host times the
// records play at.
//
// Real-time contract: init() loads the file (not RT); on(), off(), loop() and command()
// are RT-safe (the log is preloaded; no allocation).
#pragma once

#include <memory>
#include <vector>

#include "rack/core/data_component.h"
#include "rack/interfaces/robot.h"
#include "rack/replay/replay_log.h"

namespace rack::replay {
class SharedLog;
}

namespace rack::components {

class ChassisReplay final : public DataComponent<interfaces::ChassisData> {
 public:
  ChassisReplay();
  ~ChassisReplay() override;
  [[nodiscard]] std::size_t records() const noexcept { return stream_.size(); }

 protected:
  void init() override;
  HookResult on() override;
  HookResult loop() override;  // RT
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  Parameter& log_;
  Parameter& speed_;
  Parameter& strict_;
  Parameter& source_;
  std::shared_ptr<replay::SharedLog> shared_;
  std::vector<replay::OdometryRecord> stream_;  // the odometry poses played
  interfaces::ChassisParams params_{};
  std::size_t next_ = 0;
  bool have_last_ = false;
  replay::OdometryRecord last_{};
  std::atomic<bool> joined_{false};  // on() clears; loop() joins the clock
  std::atomic<uint32_t> active_pilot_{0};
};

class LadarReplay final : public DataComponent<interfaces::LadarData> {
 public:
  LadarReplay();
  ~LadarReplay() override;

 protected:
  void init() override;
  HookResult on() override;
  HookResult loop() override;  // RT

 private:
  Parameter& log_;
  Parameter& speed_;
  Parameter& strict_;
  std::shared_ptr<replay::SharedLog> shared_;
  std::unique_ptr<interfaces::LadarData> out_;
  std::size_t next_ = 0;
  std::atomic<bool> joined_{false};
};

}  // namespace rack::components
