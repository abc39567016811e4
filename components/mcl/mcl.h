// MCL (class MCL): Monte Carlo localisation of a robot in an occupancy grid map, on
// MRPT (rack/mcl/mcl_filter.h). Subscribes to a Scan2D component (getContData; each
// scan carries the odometry pose at its time), runs the particle filter when the
// robot has moved enough, publishes MclData (pose, covariance, a bounded subset of
// particles) for every scan, and sends Position UPDATE with the estimate at the scan's
// time to an optional Position component once the estimate is certain enough.
//
// INIT (kMclInit, MclInit body): re-initialise around a pose with a spread, or over
// the whole free space (global). Answered OK at once; the data task applies it before
// the next scan. ON also re-initialises, from the parameters initial_pose / global.
//
// The map is loaded in init(): a missing or malformed map file leaves the component
// in ERROR with the file, line and reason; the rest of the host keeps running.
//
// Scheduling: MRPT allocates in every update, so give the data task priority 0
// (normal scheduling) or a low SCHED_FIFO priority below every control task. The
// command task stays real-time: on(), off() and command() only exchange messages and
// flags (RT-safe); all filter work happens in loop(), which is NOT RT-safe. With
// threads 2 (the default) a large update's likelihood is shared with an executor-owned
// compute worker (Component::add_compute_worker) that runs with the data task's
// priority and on its CPUs: rackd's thread listing shows it as '<name>:likelihood'.
#pragma once

#include <atomic>
#include <memory>

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "mcl_types.h"
#include "rack/interfaces/robot.h"
#include "rack/rt/pi_mutex.h"

namespace rack::mcl {
class MclFilter;
struct MclOptions;
}  // namespace rack::mcl

namespace rack::components {

class Mcl final : public DataComponent<interfaces::MclData> {
 public:
  Mcl();
  ~Mcl() override;

  // Counters for tests and status (any thread).
  [[nodiscard]] uint64_t scans_received() const noexcept { return scans_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t position_updates_sent() const noexcept { return position_ok_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t position_updates_failed() const noexcept {
    return position_failed_.load(std::memory_order_relaxed);
  }

 protected:
  void init() override;  // loads the map, builds the filter (non-RT)
  [[nodiscard]] bool check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept override;
  HookResult on() override;
  HookResult loop() override;  // NOT RT-safe: the filter allocates (MRPT)
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  // The filter's options from the parameters (`v`: the values to check). RT-safe.
  [[nodiscard]] mcl::MclOptions read_options(const ParameterValues& v = {}) const noexcept;
  bool apply_init();  // data task: pending INIT or ON re-initialisation
  void send_position_update(int64_t time_ns) noexcept;
  // GDOS info on a change of the localisation (converged, lost and recovering,
  // re-localised, uncertain), at most one line per kEventEveryNs (later changes are
  // counted into the next line). Data task.
  void report_localisation(const interfaces::MclData& d) noexcept;

  Parameter& map_;
  InputOf<interfaces::Scan2dData>& scan2d_;  // only the newest scan counts
  Parameter& position_;
  Parameter& particles_min_;
  Parameter& particles_max_;
  Parameter& initial_pose_;
  Parameter& initial_sigma_xy_;
  Parameter& initial_sigma_phi_;
  Parameter& global_;
  Parameter& global_candidates_;
  Parameter& update_distance_;
  Parameter& update_angle_;
  Parameter& odometry_jump_;
  Parameter& beams_;
  Parameter& sigma_hit_;
  Parameter& max_range_;
  Parameter& max_corr_distance_;
  Parameter& odom_a1_;
  Parameter& odom_a2_;
  Parameter& odom_a3_;
  Parameter& odom_a4_;
  Parameter& odom_min_std_xy_;
  Parameter& odom_min_std_phi_;
  Parameter& odom_outlier_fraction_;
  Parameter& odom_outlier_scale_;
  Parameter& odometry_check_;
  Parameter& odometry_check_fraction_;
  Parameter& odometry_check_goodness_;
  Parameter& recovery_ratio_;
  Parameter& recovery_consistency_;
  Parameter& recovery_updates_;
  Parameter& inject_max_fraction_;
  Parameter& fit_min_;
  Parameter& alpha_slow_;
  Parameter& alpha_fast_;
  Parameter& threads_;
  Parameter& seed_;
  Parameter& show_particles_;
  Parameter& position_max_std_;

  std::unique_ptr<mcl::MclFilter> filter_;
  // Samples are large: kept here, not on the data task's stack.
  std::unique_ptr<interfaces::MclData> out_;
  std::unique_ptr<float[]> xs_, ys_;

  Handoff<interfaces::MclInit> init_;  // INIT from the command task to the data task
  // Set by on(): re-initialise from the parameters before the next scan.
  // Release/acquire: the data task sees everything on() wrote before it.
  std::atomic<bool> reinit_{false};
  uint32_t updates_since_init_ = 0;
  // report_localisation (data task only).
  enum class Localisation : uint8_t { kUnknown, kConverged, kLost, kUncertain };
  static constexpr int64_t kEventEveryNs = 1'000'000'000;
  Localisation localisation_ = Localisation::kUnknown;
  bool was_lost_ = false;      // lost since the last convergence: the next one is a re-localisation
  uint32_t lost_updates_ = 0;  // updates spent lost or recovering
  int64_t last_event_ns_ = 0;
  uint32_t events_unlogged_ = 0;  // changes not logged since the last line (rate limit)

  std::atomic<uint64_t> scans_{0}, no_odometry_{0}, position_ok_{0}, position_failed_{0};
};

}  // namespace rack::components
