// Monte Carlo localisation on an occupancy grid (Thrun, Burgard, Fox, Probabilistic
// Robotics, ch. 8), on MRPT's particle set (mrpt::slam::CMonteCarloLocalization2D; MRPT
// stays behind this header, linked privately to the MCL target only).
//
// One filter step (update()): KLD-sampling (Fox 2003) draws the new particles from the
// weighted old ones (a low-variance draw, taken in random order; the KLD bins count the
// drawn source poses, the posterior's support, as AMCL does), each moved by the
// odometry increment plus noise (the motion model below), then weighs each by the scan
// (the likelihood field below), split over `threads` threads (the caller's and a compute
// worker), then the recovery test.
// What this class adds over MRPT's filter:
// - the map conversion from rack::maps::OccupancyMap (free/occupied/unknown cells);
// - robot-frame scan points as the observation (Scan2D output: any bearings, no
//   regular beam layout needed), evenly subsampled to `beams` points;
// - update gating: the filter runs only after `update_distance` or `update_angle` of
//   odometry (the estimate in between is the last one composed with odometry);
// - a motion model with a heavy tail: MRPT's Gaussian model (a1..a4, minimum std devs),
//   plus a fraction `odom_outlier_fraction` of the particles moved with
//   `odom_outlier_scale` times that noise, so that one odometry read-out that stalled or
//   slipped (real odometry does) does not leave the whole cloud behind;
// - an odometry check: the scan matched against the previous update's scan (ICP); when
//   that increment disagrees with the odometry's beyond the motion model, part of the
//   particles moves by the scan's increment (odometry that stalled for a read-out);
// - recovery that tells a kidnap from a bad scan (see the options): random particles
//   only after the scan fit stayed low for several updates;
// - initialisation around a pose with a spread, or globally over the free space.
//
// Likelihood field (Thrun's, as MRPT's lmLikelihoodField_Thrun): a point at distance d
// from the nearest occupied cell has p = z_hit * exp(-d^2 / (2 sigma_hit^2)) +
// z_random / max_range, d capped at max_corr_distance; a point outside the map counts
// as d = max_corr_distance. Precomputed per cell (a distance transform at
// construction), so a scan costs one look-up per point and particle, read-only and
// shared by the threads. The scan's log-likelihood is the sum over points times
// likelihood_power.
//
// The scan fit w of a particle is the per-point geometric mean of the likelihood,
// exp(log-likelihood / points), in (0, 1]: "how well does an average point fit".
//
// Coordinates: map frame of the OccupancyMap (origin applied); odometry poses are in
// the odometry frame and only their increments are used.
//
// Real-time contract: nothing here is RT-safe (allocates; with threads > 1 hands half of
// the likelihood to a compute worker, rack/core/compute_worker.h, and waits for it); run
// it in a non-RT (priority 0) or low-priority task. The filter makes no thread: the
// worker is the caller's (the MCL component's is the executor's,
// Component::add_compute_worker). Thread-safety: one thread per instance.
// Draws come from the instance's own generator (seed), so instances are independent.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>

#include "rack/maps/occupancy_map.h"

namespace rack {
class ComputeWorker;
}  // namespace rack

namespace rack::mcl {

struct MclOptions {
  // Particle count (KLD-sampling; Fox 2003). min == max: fixed size.
  uint32_t particles_min = 100;
  uint32_t particles_max = 2000;
  double kld_bin_xy = 0.10;    // m
  double kld_bin_phi = 0.087;  // rad (5 deg)
  double kld_delta = 0.02;     // KLD quantile (1 - delta)
  double kld_epsilon = 0.05;   // KLD error bound
  // Likelihood field (Thrun): p(z) = z_hit * N(dist; sigma) + z_random / max_range.
  double sigma_hit = 0.10;  // m
  double z_hit = 0.95;
  double z_random = 0.05;
  double max_range = 30.0;         // m (z_random's support)
  double max_corr_distance = 0.5;  // m: distances beyond count as this far
  uint32_t beams = 60;             // points used per scan (evenly chosen); 0: all
  double likelihood_power = 1.0;   // exponent on the scan likelihood (< 1 flattens)
  // Odometry motion model, MRPT's Gaussian model (CActionRobotMovement2D): for an
  // increment of d metres and a radians, std dev of x and y (robot frame)
  // max(odom_min_std_xy, a1 d + a2 a), of the heading max(odom_min_std_phi, a3 d + a4 a).
  double odom_a1 = 0.20;           // m/m: translation noise per metre
  double odom_a2 = 0.001;          // m/rad: translation noise per radian turned
  double odom_a3 = 0.05;           // rad/m: rotation noise per metre (heading drift)
  double odom_a4 = 0.05;           // rad/rad: rotation noise per radian
  double odom_min_std_xy = 0.01;   // m
  double odom_min_std_phi = 0.01;  // rad
  // The heavy tail: this fraction of the particles moves with odom_outlier_scale times
  // the noise above (0: MRPT's model alone).
  double odom_outlier_fraction = 0.10;
  double odom_outlier_scale = 3.0;
  // An odometry increment longer than this between two consecutive scans is a jump (an
  // Odometry RESET, a restarted driver): that one increment is dropped (the motion
  // before it is kept) instead of moving the particles (0: off). Far above any real
  // motion between two scans, an odometry catch-up after a stall included.
  double odometry_jump = 5.0;  // m
  // The odometry check (scan-to-scan): each filter update also matches this scan
  // against the scan of the previous filter update (MRPT's ICP, started from the
  // odometry increment). When the match pairs at least odometry_check_goodness of the
  // points and its increment differs from the odometry's by more than odometry_check
  // standard deviations of the motion model (in x-y or in heading; the std devs of the
  // scan's increment, at least sigma_hit and 0.05 rad: smaller disagreements the
  // scan's weighting settles by itself), and the scan fits the map clearly better from
  // the last estimate moved by the scan's increment than by the odometry's (by 0.25 in
  // mean log-likelihood per point: ICP can settle in a wrong minimum where the walls
  // repeat), a share odometry_check_fraction of the
  // particles moves by the scan's increment instead (with the motion model's noise for
  // it), the rest by the odometry's, and the scan weighs both. For odometry whose
  // read-out stalls and then catches up (30-80 % of a step reported, the rest with the
  // next one): no Gaussian motion model of sensible width covers those two scans, and
  // the particles moved by the odometry alone fall behind. The check is skipped while
  // the scans fit the map worse than usual (w_fast below recovery_ratio times the
  // long-term fit since the estimate converged, see the recovery below): among a crowd,
  // ICP pairs people with people; and while the estimate has not converged (position
  // std dev above 0.5 m or heading's above 0.3 rad: after a global start the mean lies
  // between look-alike places, and the map test means nothing). ICP is not run when
  // its answer could not count: when the scan already fits from the odometry's
  // increment within 0.25 per point of a perfect fit. Scans are matched with at most
  // 180 points. Along a corridor ICP stays at the odometry's increment. 0: off.
  double odometry_check = 2.0;           // std devs of the motion model
  double odometry_check_fraction = 0.5;  // of the particles, moved by the scan's increment
  double odometry_check_goodness = 0.5;  // share of the points ICP paired, (0, 1]
  // Update gating.
  double update_distance = 0.10;  // m of odometry travel
  double update_angle = 0.10;     // rad of odometry turn
  // Recovery that tells a kidnap from a bad scan. Two pieces of evidence, each with a
  // short- and long-term average (AMCL's w_fast, w_slow; Thrun et al. table 8.3): the
  // scan fit (below) and the scan's consistency with the map at the estimate (the
  // fraction of beams that do not pass through an occupied cell before their end: a
  // person or a crowd makes short readings, which are consistent; a robot that is
  // elsewhere sees through the map's walls). The robot counts as lost only when both
  // dropped, w_fast < recovery_ratio * w_slow and c_fast < recovery_consistency * c_slow,
  // for recovery_updates consecutive updates; then, while it stays so, (1 - w_fast /
  // w_slow) * particles_max poses (at most inject_max_fraction of particles_max) are
  // added per update, weighted by the scan like the others: each the best fitting of
  // global_candidates random poses over the free space (all weighed by the scan; a
  // uniform pose rarely lands near enough to the true one for the scan to tell it).
  // While lost, the long-term averages hold the values tracking gave them (they no
  // longer sink to the lost filter's poor fit, which stopped the injection after 40-140
  // updates, tens of metres off: bench/RESULTS.md). After init_global() the long-term
  // averages start at a perfect fit, so a cloud that converged to a wrong place counts
  // as lost too; they hold only once the filter has tracked as usual (not lost, the
  // estimate converged).
  double alpha_slow = 0.01;
  double alpha_fast = 0.2;
  double recovery_ratio = 0.5;
  double recovery_consistency = 0.9;
  uint32_t recovery_updates = 5;
  double inject_max_fraction = 0.50;  // of particles_max, added per update at most (0: no recovery)
  // Also count an update as "low" while w_fast stays below this absolute fit (0: off; a
  // real scan's fit depends on clutter and the map, so off by default).
  double fit_min = 0.0;
  // Global localisation: init_global() spreads this many times particles_max poses over
  // the free space; the first update weighs them all (no resampling before it) and
  // keeps the particles_max that fit the scan best, equally weighted; the next update
  // resamples those (KLD). The first scan finds the right place only if some pose lies
  // near it: more candidates, once, for one costlier update. 5 (bench/RESULTS.md,
  // issue 18): within 2x MRPT alone's travel in 9-10 of 10 seeds on each real log
  // (1: seattle 5-7), the simulated office within 15 m in 18 of 20 seeds (1: 16).
  // Recovery (above) also draws this many random poses per injected one and keeps
  // the best (1: uniform injection).
  uint32_t global_candidates = 5;
  // Threads evaluating the likelihood (1: the caller's only; 2: the caller's and the
  // compute worker given to the constructor, used for an update of at least 100 000
  // particles x points, below which its wake-up costs more than it saves; without a
  // worker, or one that no thread serves, the caller's thread does all of it).
  uint32_t threads = 2;
  // Random seed for this filter's draws (0: from the clock).
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
  MclPose pose;               // mean of the particles (map frame)
  double covariance[9] = {};  // row-major over (x, y, phi)
  uint32_t particles = 0;
  float ess = 0.0F;                   // effective sample size / particles, (0, 1]
  uint32_t injected = 0;              // at the last filter update
  uint64_t updates = 0;               // filter updates since the last init
  double w_slow = 0.0, w_fast = 0.0;  // scan-fit averages (recovery)
  double fit = 0.0;                   // mean scan fit at the last update
  double consistency = 0.0;           // fraction of the last scan's beams not through a wall at the estimate
  uint32_t low_updates = 0;           // consecutive updates with w_fast < recovery_ratio * w_slow
  uint64_t recoveries = 0;            // updates that injected (since the last init)
  uint64_t odometry_jumps = 0;        // odometry discontinuities dropped (since construction)
  // The odometry check: updates whose scan-to-scan increment disagreed with the
  // odometry (part of the particles moved by the scan's), since construction, and
  // whether the last update was one.
  uint64_t odometry_disagreements = 0;
  bool odometry_disagreed = false;
};

class MclFilter {
 public:
  // Converts the map (throws std::invalid_argument when it has no free cell or a
  // rotated origin, which MRPT's axis-aligned grid cannot represent). Starts with
  // particles_max poses uniformly over the free space (no candidates round: call
  // init_global() or init_pose() before the first update). `worker`: the likelihood's
  // second thread for threads 2 (not owned; it must outlive the filter); nullptr: none.
  MclFilter(const maps::OccupancyMap& map, const MclOptions& options, ComputeWorker* worker = nullptr);
  ~MclFilter();
  MclFilter(const MclFilter&) = delete;
  MclFilter& operator=(const MclFilter&) = delete;

  // Particles (particles_max of them) drawn around a pose: normal in x and y with
  // sigma_xy, in phi with sigma_phi. The next update() runs the filter whatever the
  // odometry did.
  void init_pose(const MclPose& pose, double sigma_xy, double sigma_phi);
  // Particles (particles_max times global_candidates) uniformly over the map's free
  // cells and all headings; the first update keeps the particles_max best of them.
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
