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
// Time base: every sample carries the log's own time (the record's time stamp in
// seconds, as nanoseconds), at any speed. Downstream components (Odometry, Scan2D,
// MCL, Position, TrajectoryWriter) work in that time base, so a replay at speed 20
// produces the same samples as one at speed 1, and a trajectory comes out in the
// log's time.
//
// Both components that name the same file share its replay clock (one per file and
// process): log time t plays at host time anchor + (t - t_first) / speed, the anchor
// being when the first of them was switched on, so scans and odometry stay in step.
// A component switched on within 2 s of that plays from the log's beginning; one
// switched on later (or again) joins the running clock and skips what has played.
// At the end of the log each says so once (GDOS info: how many records it played from
// which file) and ends its stream (DataComponentBase::end_stream): it stays ENABLED, its
// consumers get END_OF_STREAM, stay ENABLED and pass the end on; nothing goes to
// ERROR, nothing retries. OFF and ON again joins the clock at the end: the end again.
//
// Pacing (LadarReplay 'pace': the component at the end of the pipeline, e.g. MCL or
// a TrajectoryWriter): nothing plays until that component is ENABLED (so it and
// everything before it listen from the first record on); scan k is released only
// once the paced component has published a sample stamped at or after scan k-1's
// time (or pace_timeout_ms passed: counted, shown in the status line); the
// ChassisReplay publishes odometry only up to the first record at or after the next
// scan to be released. With speed 0 there is no clock at all: the log plays as fast
// as the pipeline takes it, and no consumer skips or loses a scan, so the estimates
// are those of a replay at speed 1.
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
  bool ended_ = false;  // data task: the end of the log was announced (on() clears via joined_)
};

// LadarReplay's status: what has played, how the pace went (for describe_status).
struct LadarReplayProgress {
  std::atomic<uint64_t> scans{0};          // scans published
  std::atomic<int64_t> last_time_ns{0};    // the last one's (log) time
  std::atomic<uint64_t> pace_timeouts{0};  // scans released after pace_timeout_ms
};

class LadarReplay final : public DataComponent<interfaces::LadarData> {
 public:
  LadarReplay();
  ~LadarReplay() override;
  void describe_status(std::string& out) const override;  // not RT (rackd's main thread)

 protected:
  void init() override;
  HookResult on() override;
  HookResult loop() override;  // RT

 private:
  // Pacing, data task: the paced component is ENABLED / has output at or after
  // `time_ns` (one GET_STATUS or GET_DATA each).
  bool pace_enabled() noexcept;
  bool pace_reached(int64_t time_ns) noexcept;

  Parameter& log_;
  Parameter& speed_;
  Parameter& strict_;
  Parameter& pace_;
  Parameter& pace_timeout_ms_;
  std::shared_ptr<replay::SharedLog> shared_;
  std::unique_ptr<interfaces::LadarData> out_;
  std::unique_ptr<std::byte[]> reply_;  // GET_DATA replies of the paced component (64 KB)
  std::size_t next_ = 0;
  bool paced_ = false;           // 'pace' names a component (set in init)
  int64_t pace_wait_since_ = 0;  // host time the release of scan next_ began to wait (0: not waiting)
  std::atomic<bool> joined_{false};
  bool ended_ = false;  // data task: the end of the log was announced
  LadarReplayProgress progress_;
};

}  // namespace rack::components
