// Monte Carlo localisation on an occupancy grid, built on MRPT's particle filter
// (mrpt::slam::CMonteCarloLocalization2D; MRPT stays behind this header, linked
// privately to the MCL target only).
//
// What MRPT gives: the particle set, the odometry motion model
// (CActionRobotMovement2D, Gaussian model), KLD-sampling (adaptive particle count
// between particles_min and particles_max) and Thrun's likelihood field on a
// COccupancyGridMap2D. What this class adds:
// - the map conversion from rack::maps::OccupancyMap (free/occupied/unknown cells);
// - robot-frame scan points as the observation (Scan2D output: any bearings, no
//   regular beam layout needed), evenly subsampled to `beams` points;
// - update gating: the filter runs only after `update_distance` or `update_angle` of
//   odometry (the estimate in between is the last one composed with odometry);
// - random particle injection for recovery (augmented MCL, Thrun et al.,
//   Probabilistic Robotics, table 8.3): short- and long-term averages w_fast, w_slow
//   of the scan fit; while w_fast < w_slow, p = 1 - w_fast / w_slow; also while
//   w_fast < fit_min, p = 1 - w_fast / fit_min (a filter that converged to a wrong
//   place never had a good fit to drop from). p * particles_max poses (p at most
//   `inject_max_fraction`) drawn uniformly over the map's free cells are added,
//   weighted by the current scan;
// - initialisation around a pose with a spread, or globally over the free space.
//
// The scan fit w of a particle is the per-point geometric mean of the likelihood
// field, exp(log-likelihood / points): unlike the product over points it does not
// underflow, and it reads as "how well does an average point fit" (in (0, 1]).
//
// Coordinates: map frame of the OccupancyMap (origin applied); odometry poses are in
// the odometry frame and only their increments are used.
//
// Real-time contract: nothing here is RT-safe (MRPT allocates in every update); run it
// in a non-RT (priority 0) or low-priority task. Thread-safety: one thread per
// instance. MRPT draws from one process-wide random generator; updates of all
// instances in a process are serialised by a process-wide lock for that reason.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

#include "rack/maps/occupancy_map.h"

namespace rack::mcl {

struct MclOptions {
  // Particle count (KLD-sampling; Fox 2003). min == max: fixed size.
  uint32_t particles_min = 100;
  uint32_t particles_max = 2000;
  double kld_bin_xy = 0.10;   // m
  double kld_bin_phi = 0.087; // rad (5 deg)
  double kld_delta = 0.02;    // KLD quantile (1 - delta)
  double kld_epsilon = 0.05;  // KLD error bound
  // Likelihood field (Thrun): p(z) = z_hit * N(dist; sigma) + z_random / max_range.
  double sigma_hit = 0.10;        // m
  double z_hit = 0.95;
  double z_random = 0.05;
  double max_range = 30.0;        // m (z_random's support)
  double max_corr_distance = 0.5; // m: distances beyond count as this far
  uint32_t beams = 60;            // points used per scan (evenly chosen); 0: all
  double likelihood_power = 1.0;  // exponent on the scan likelihood (< 1 flattens)
  // Odometry motion model (MRPT's Gaussian model).
  double odom_a1 = 0.05;          // m/m: translation noise per metre
  double odom_a2 = 0.001;         // m/rad: translation noise per radian turned
  double odom_a3 = 0.02;          // rad/m: rotation noise per metre
  double odom_a4 = 0.05;          // rad/rad: rotation noise per radian
  double odom_min_std_xy = 0.01;  // m
  double odom_min_std_phi = 0.01; // rad
  // Odometry increments longer than this between two scans are a jump (an Odometry
  // RESET): MCL re-anchors on the new odometry instead of moving the particles (0: off).
  double odometry_jump = 1.0;     // m
  // Update gating.
  double update_distance = 0.10;  // m of odometry travel
  double update_angle = 0.10;     // rad of odometry turn
  // Recovery (augmented MCL).
  double alpha_slow = 0.01;
  double alpha_fast = 0.2;
  double inject_max_fraction = 0.10;  // of particles_max, added per update at most
  // Inject also while the short-term fit stays below this (0: only on a drop).
  double fit_min = 0.6;
  // Random seed for this filter's draws and MRPT's generator (0: from the clock).
  uint64_t seed = 0;
};

// Throws std::invalid_argument naming the option when one is out of range.
void validate(const MclOptions& options);
// The same checks without throwing: nullptr, or the (static) reason. RT-safe.
[[nodiscard]] const char* check_options(const MclOptions& options) noexcept;

struct MclPose {
  double x = 0.0, y = 0.0, phi = 0.0;
};

struct MclEstimate {
  MclPose pose;                 // mean of the particles (map frame)
  double covariance[9] = {};    // row-major over (x, y, phi)
  uint32_t particles = 0;
  float ess = 0.0F;             // effective sample size / particles, (0, 1]
  uint32_t injected = 0;        // at the last filter update
  uint64_t updates = 0;         // filter updates since the last init
  double w_slow = 0.0, w_fast = 0.0;  // scan-fit averages (recovery)
  double fit = 0.0;             // mean scan fit at the last update
  uint64_t odometry_jumps = 0;  // odometry discontinuities re-anchored on (since construction)
};

class MclFilter {
 public:
  // Converts the map (throws std::invalid_argument when it has no free cell or a
  // rotated origin, which MRPT's axis-aligned grid cannot represent).
  MclFilter(const maps::OccupancyMap& map, const MclOptions& options);
  ~MclFilter();
  MclFilter(const MclFilter&) = delete;
  MclFilter& operator=(const MclFilter&) = delete;

  // Particles (particles_max of them) drawn around a pose: normal in x and y with
  // sigma_xy, in phi with sigma_phi. The next update() runs the filter whatever the
  // odometry did.
  void init_pose(const MclPose& pose, double sigma_xy, double sigma_phi);
  // Particles (particles_max) uniformly over the map's free cells and all headings.
  void init_global();

  // One scan: robot-frame points (max-range readings left out by the caller) and the
  // odometry pose at the scan's time. Returns true when the filter ran (gating passed,
  // or first scan after an init); false when only the odometry was accumulated.
  bool update(const MclPose& odometry, std::span<const float> xs, std::span<const float> ys);

  // The estimate: after a filter update, the particles' mean and covariance; between
  // updates that mean composed with the odometry travelled since.
  [[nodiscard]] MclEstimate estimate() const;
  // Up to out.size() particles, evenly spaced through the set, with their weights
  // normalised over the ones returned. Returns how many were written.
  std::size_t sample_particles(std::span<float> x, std::span<float> y, std::span<float> phi,
                               std::span<float> weight) const;
  [[nodiscard]] const MclOptions& options() const noexcept;
  void set_options(const MclOptions& options);  // validates; takes effect at the next update

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rack::mcl
