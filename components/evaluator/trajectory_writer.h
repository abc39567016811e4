// TrajectoryWriter (class Evaluator): writes the poses a localisation component
// estimates (MCL, at each scan's time; or Position) to a text file, one `t x y theta`
// line per estimate (t in seconds of the samples' time base: a replayed log's own
// time, see replay_components.h), and when the input ends compares them with a
// reference trajectory file in the same format, if one is given:
//
//   ATE RMSE       root mean square of the position error over the reference poses
//   lost           reference poses whose estimate is more than lost_threshold off
//   rotation RMSE  root mean square of the heading error (degrees)
//   unmatched      reference poses without an estimate (before the first, after the
//                  last, or in a gap longer than max_gap_ms between two estimates)
//
// The estimate at a reference pose's time is the one at that time, or the linear
// interpolation of the two around it (heading the shorter way round). No alignment:
// the estimate and the reference are in the same (map) frame.
//
// The input ends when the source (a declared input) leaves ENABLED (its ERROR), ends
// its stream, or sends nothing for silence_ms; then the file is flushed, the error logged (GDOS, info) and
// shown in the status line (rackd --status, final status; `rackctl get-data`: the
// EvaluatorData fields mcl_* and lost), and with exit_when_done rackd is asked to
// stop (SIGTERM to its own process, as `kill` would). With LadarReplay's `pace`
// naming this component, the replay starts only once the writer is ENABLED
// (subscribed to its source), so the first estimates are not missed, and each scan
// waits for the writer to have the previous estimate: nothing is skipped.
//
// Real-time contract: NOT RT-safe: loop() writes the file (buffered stdio) and
// grows the trajectory in memory, and init() reads the reference. Give the data task
// priority 0 (normal scheduling), as MCL's; nothing real-time waits for it.
// describe_status() runs on rackd's main thread.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "rack/core/data_component.h"
#include "evaluator_types.h"
#include "rack/interfaces/robot.h"
#include "rack/rt/pi_mutex.h"

namespace rack::components {

// One pose of a trajectory, at time t (s).
struct TimedPose {
  double t = 0.0, x = 0.0, y = 0.0, phi = 0.0;
};

// The error of an estimated trajectory against a reference (pure functions; not RT).
struct TrajectoryError {
  std::size_t reference = 0;   // reference poses
  std::size_t matched = 0;     // with an estimate at their time
  std::size_t lost = 0;        // of those, further than the threshold
  double ate_rmse = 0.0;       // m
  double max_error = 0.0;      // m
  double rotation_rmse = 0.0;  // rad
};
// `estimate` sorted by time. A reference pose is matched when an estimate lies within
// 1 us of its time or two estimates at most max_gap apart lie around it.
[[nodiscard]] TrajectoryError trajectory_error(const std::vector<TimedPose>& estimate,
                                               const std::vector<TimedPose>& reference, double lost_threshold,
                                               double max_gap);
// Parses `t x y theta` lines ('#' comments and blank lines skipped; further columns
// ignored) from memory; `name` is used in errors. Throws std::runtime_error
// "name:line: reason" for a malformed line, a non-finite value or times that go
// backwards (a plain function on a byte buffer, for the fuzz harnesses).
[[nodiscard]] std::vector<TimedPose> parse_trajectory_text(std::string_view text, const std::string& name);
// Reads and parses a file; also throws ("path: why") when it cannot be read, is not a
// regular file (a FIFO, a directory, a device) or is larger than kMaxTrajectoryFileBytes.
inline constexpr uint64_t kMaxTrajectoryFileBytes = 256u << 20;  // 256 MiB: ~6 M poses
[[nodiscard]] std::vector<TimedPose> read_trajectory_file(const std::string& path);

class TrajectoryWriter final : public DataComponent<interfaces::EvaluatorData> {
 public:
  TrajectoryWriter();
  ~TrajectoryWriter() override;
  void describe_status(std::string& out) const override;

 protected:
  void init() override;
  void off() override;
  HookResult loop() override;  // NOT RT-safe (file output)
  void cleanup() override;

 private:
  void take() noexcept;  // the source's newest estimate: into the file and the trajectory
  void finish() noexcept;

  InputOneOf<interfaces::MclData, interfaces::PositionData>& source_;
  Parameter& file_;
  Parameter& reference_;
  Parameter& lost_threshold_;
  Parameter& max_gap_ms_;
  Parameter& exit_when_done_;
  std::FILE* out_ = nullptr;
  std::vector<TimedPose> reference_poses_;
  std::vector<TimedPose> poses_;  // data task
  interfaces::EvaluatorData data_{};
  bool finished_ = false;  // data task
  mutable rt::PiMutex summary_mutex_;
  std::string summary_;  // guarded by summary_mutex_: the status line's text
};

}  // namespace rack::components
