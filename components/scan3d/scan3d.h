// Scan3D (class Scan3D): 3-D scans from a 2-D Ladar turned by a ServoDrive (RACK's
// roll, pitch and yaw scan modes), or played from PCD files; processed with PCL
// (voxel grid, statistical outlier removal, RANSAC ground plane, point types) and
// published as Scan3dData (scan3d_types.h).
//
// Ladar + ServoDrive (declared inputs: the framework switches both on and subscribes
// before on()): on() sends the drive to angle_min. Then it sweeps: MOVE_POS to angle_max, and every
// ladar scan taken during the sweep is placed in 3-D with the drive's angle at each
// beam's time, interpolated in the drive's position stream (a scan waits in a small
// queue until the drive has reported a position after its end). When the drive
// reports the target reached, the sweep is one 3-D scan: the drive is sent back the
// other way (the next sweep) and the scan is processed and published. Without
// `odometry` the robot should stand still during a sweep (points are in the robot
// frame, each where the robot was at its beam's time), and a scan carries the time of
// its first 2-D scan.
//
// Motion compensation (`odometry`: an Odometry or Position component, subscribed
// like the ladar and the drive, every sample): its poses go into a ring of 256 in the
// assembler (allocated in init()), each beam is placed with the robot's pose at the
// beam's time, and the finished sweep is expressed in the robot frame at its END: the
// published scan then carries the end time (the end of its last 2-D scan; duration_ns
// before it is the first). A 2-D scan waits until a pose at or after its end has
// arrived. The ring holds 256 poses: with a fast odometry (1 kHz) ask for a longer
// odometry_period_ms, so that they cover the time a scan's processing keeps the data
// task away (older 2-D scans are skipped as bad input). Odometry is the better
// source: Position jumps at an UPDATE, and an odometry RESET during a sweep smears
// that one sweep.
//
// PCD files (`pcd`: a file or a directory of *.pcd, played in name order every
// pcd_period_ms, looping if pcd_loop): each file is one scan.
//
// Commands: GET_RANGE_IMAGE (kScan3dGetRangeImage) and STORE_DATA (kScan3dStoreData)
// for the newest scan; the command task hands them to the data task (a Handoff of up
// to 4) and wakes it, and the data task serves them (PCL and file I/O never run in the
// command task).
//
// Bad input, each counted in Scan3dData.bad_input and logged (the first of each kind,
// then every 100th with the count), and SKIPPED, because one bad scan or file says
// nothing about the next: a malformed PCD file (file:line: reason), an empty ladar
// scan (no echo), a malformed ladar scan, a scan older than the drive's history, a
// drive position or odometry pose that is not finite, a scan older than the odometry's
// 256 poses. A DATA message that does not decode (wrong size
// for its producer's type) is also counted as malformed in GET_STATS and logged by
// the data task's input path (DataComponentBase::receive). A
// ladar, drive or odometry that falls silent for silence_ms (for the odometry also:
// whose newest pose is more than silence_ms older than a waiting 2-D scan, so that no
// pose covers its beams), or a drive that does not finish a sweep within
// sweep_timeout_s, puts the component in ERROR (on() retries).
//
// Scheduling: PCL allocates, so the DATA task must run at priority 0 (normal
// scheduling) or a low SCHED_FIFO priority below every control task, as MCL's; its
// loop() is NOT RT-safe. The command task stays real-time: on(), off() and command()
// only exchange messages and copy into preallocated slots.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "scan3d_types.h"
#include "common/scan3d_geometry.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/robot.h"

namespace rack::scan3d {
class Scan3dAssembler;
class Scan3dPipeline;
struct PipelineOptions;
}  // namespace rack::scan3d

namespace rack::components {

class Scan3d final : public DataComponent<interfaces::Scan3dData> {
 public:
  Scan3d();
  ~Scan3d() override;

  // Counters (any thread).
  [[nodiscard]] uint64_t scans_published() const noexcept { return published_scans_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t bad_input() const noexcept { return bad_input_.load(std::memory_order_relaxed); }
  void describe_status(std::string& out) const override;

 protected:
  void init() override;  // reads the parameters, lists the PCD files, allocates (non-RT)
  [[nodiscard]] bool check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept override;
  HookResult on() override;
  HookResult loop() override;  // NOT RT-safe: PCL and file I/O
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  enum class Phase : uint8_t { kToStart, kSweeping };
  struct Request {
    tims::MessageHeader header{};
    interfaces::Scan3dRangeImageRequest range{};
    interfaces::Scan3dStoreData store{};
  };
  static constexpr std::size_t kMaxRequests = 4;
  struct Requests {
    Request item[kMaxRequests];
    std::size_t count = 0;
  };
  static constexpr std::size_t kPendingScans = 16;

  // The pipeline's options from the parameters (`v`: the values to check). RT-safe.
  [[nodiscard]] scan3d::PipelineOptions read_options(const ParameterValues& v = {}) const noexcept;
  enum class BadKind : uint8_t { kPcdFile, kLadarScan, kSweep, kDrive, kPose };
  static constexpr std::size_t kBadKinds = 5;
  // Counts one bad input of `kind`; logs `detail` (rate-limited) unless it is null
  // (a DATA message that did not decode: the input path has logged it).
  void count_bad(BadKind kind, const char* detail) noexcept;
  // Counts the DATA messages of `in` that did not decode since it had `before`.
  void count_malformed(const InputPort& in, uint64_t before, BadKind kind) noexcept;
  // One sample of each input, as receive() delivers it (`now`: the loop's start).
  void take_pose(int64_t now) noexcept;
  void take_drive(int64_t now) noexcept;
  void take_scan(int64_t now) noexcept;
  HookResult loop_ladar(int64_t now);
  HookResult loop_files(int64_t now);
  bool move_drive(double target) noexcept;
  void finish_scan(int64_t time_ns, int64_t duration_ns, uint8_t mode, uint32_t ladar_scans, const float* x,
                   const float* y, const float* z, const float* intensity, std::size_t n);
  void serve_requests();
  void reply_error_from_data(const tims::MessageHeader& request, const std::string& reason) noexcept;

  InputOf<interfaces::LadarData>& ladar_;
  InputOf<interfaces::ServoDriveData>& servo_;
  InputOneOf<interfaces::OdometryData, interfaces::PositionData>& odometry_;
  Parameter& pcd_;
  Parameter& mode_;
  Parameter& mount_x_;
  Parameter& mount_y_;
  Parameter& mount_z_;
  Parameter& angle_min_;
  Parameter& angle_max_;
  Parameter& sweep_velocity_;
  Parameter& angle_tolerance_;
  Parameter& range_min_;
  Parameter& range_max_;
  Parameter& voxel_size_;
  Parameter& outlier_neighbours_;
  Parameter& outlier_std_;
  Parameter& ground_tolerance_;
  Parameter& ground_max_tilt_;
  Parameter& ground_max_height_;
  Parameter& ceiling_height_;
  Parameter& max_points_;
  Parameter& range_image_res_deg_;
  Parameter& store_dir_;
  Parameter& pcd_period_ms_;
  Parameter& pcd_loop_;
  Parameter& sweep_timeout_s_;

  uint8_t mode_id_ = interfaces::kScan3dModePitch;
  bool file_source_ = false;
  bool compensate_ = false;  // odometry given
  std::vector<std::string> files_;
  std::unique_ptr<scan3d::Scan3dAssembler> assembler_;
  std::unique_ptr<scan3d::Scan3dPipeline> pipeline_;
  std::unique_ptr<interfaces::Scan3dData> out_;
  std::unique_ptr<interfaces::Scan3dRangeImage> image_;
  std::unique_ptr<interfaces::LadarData[]> pending_;  // ladar scans waiting for the drive
  int64_t pending_time_[kPendingScans] = {};
  std::size_t pending_head_ = 0, pending_count_ = 0;

  // Data task state.
  Phase phase_ = Phase::kToStart;
  double sweep_from_ = 0.0, sweep_to_ = 0.0;
  int64_t sweep_start_ns_ = 0;  // host time the current sweep started (drive left its start)
  int64_t sweep_end_ns_ = 0;    // drive sample time that reached the target (0: not yet)
  int64_t sweep_started_mono_ = 0;
  int64_t newest_ladar_ns_ = 0;
  int64_t last_ladar_mono_ = 0, last_drive_mono_ = 0, last_pose_mono_ = 0;
  interfaces::ServoDriveData drive_{};
  int64_t drive_time_ns_ = 0;
  bool have_drive_ = false;
  bool have_scan_ = false;    // out_ holds a published scan
  int64_t scan_time_ns_ = 0;  // its time
  std::size_t next_file_ = 0;
  int64_t next_file_mono_ = 0;
  uint32_t scan_number_ = 0;
  uint64_t bad_kinds_[kBadKinds] = {};  // per BadKind, for rate-limited logging

  // Command task -> data task: GET_RANGE_IMAGE / STORE_DATA requests.
  Handoff<Requests> requests_;

  // Status for other threads (relaxed: counters and readings).
  std::atomic<uint64_t> published_scans_{0}, bad_input_{0}, dropped_scans_{0};
  std::atomic<uint32_t> last_points_{0};
  std::atomic<float> last_ms_{0.0F};
};

}  // namespace rack::components
