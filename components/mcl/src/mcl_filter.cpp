#include "rack/mcl/mcl_filter.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/distributions.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/slam/CICP.h>
#include <mrpt/slam/CMonteCarloLocalization2D.h>
#include <numbers>
#include <random>
#include <stdexcept>
#include <unordered_set>
#include <vector>

#include "rack/core/compute_worker.h"

namespace rack::mcl {

namespace {

double wrap(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

// Squared Euclidean distance transform of one line (Felzenszwalb and Huttenlocher,
// "Distance Transforms of Sampled Functions", 2012): d[q] = min_p (q - p)^2 + f[p], by
// the lower envelope of the parabolas rooted at each p. f holds 0 (occupied) or kFar.
constexpr double kFar = 1e12;
void edt_1d(const std::vector<double>& f, std::vector<double>& d, std::vector<int>& v, std::vector<double>& z) {
  const int n = static_cast<int>(f.size());
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const auto at = [](auto& vec, int i) -> auto& { return vec[static_cast<std::size_t>(i)]; };
  int k = 0;
  at(v, 0) = 0;
  at(z, 0) = -kInf;
  at(z, 1) = kInf;
  for (int q = 1; q < n; ++q) {
    double s = 0;
    for (;;) {
      const int p = at(v, k);
      s = ((at(f, q) + double(q) * q) - (at(f, p) + double(p) * p)) / (2.0 * (q - p));
      if (s > at(z, k)) break;
      --k;
    }
    ++k;
    at(v, k) = q;
    at(z, k) = s;
    at(z, k + 1) = kInf;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (at(z, k + 1) < q) ++k;
    const int p = at(v, k);
    at(d, q) = double(q - p) * (q - p) + at(f, p);
  }
}

}  // namespace

const char* check_options(const MclOptions& o) noexcept {
  if (o.particles_min < 1) return "particles_min must be at least 1";
  if (o.particles_max < o.particles_min) return "particles_max must be at least particles_min";
  if (o.particles_max > 1'000'000) return "particles_max must be at most 1000000";
  if (!(o.kld_bin_xy > 0) || !(o.kld_bin_phi > 0)) return "kld_bin_xy and kld_bin_phi must be positive";
  if (!(o.kld_delta > 0 && o.kld_delta < 1)) return "kld_delta must be in (0, 1)";
  if (!(o.kld_epsilon > 0)) return "kld_epsilon must be positive";
  if (!(o.sigma_hit > 0)) return "sigma_hit must be positive";
  if (!(o.z_hit >= 0 && o.z_random > 0)) return "z_hit must be >= 0 and z_random > 0";
  if (!(o.max_range > 0) || !(o.max_corr_distance > 0)) return "max_range and max_corr_distance must be positive";
  if (!(o.likelihood_power > 0 && o.likelihood_power <= 1)) return "likelihood_power must be in (0, 1]";
  if (!(o.odom_a1 >= 0 && o.odom_a2 >= 0 && o.odom_a3 >= 0 && o.odom_a4 >= 0)) return "odom_a1..odom_a4 must be >= 0";
  if (!(o.odom_min_std_xy >= 0 && o.odom_min_std_phi >= 0)) return "odom_min_std_xy and odom_min_std_phi must be >= 0";
  if (!(o.odom_outlier_fraction >= 0 && o.odom_outlier_fraction <= 1)) return "odom_outlier_fraction must be in [0, 1]";
  if (!(o.odom_outlier_scale >= 1 && o.odom_outlier_scale <= 1000)) return "odom_outlier_scale must be in [1, 1000]";
  if (!(o.odometry_jump >= 0)) return "odometry_jump must be >= 0";
  if (!(o.update_distance >= 0 && o.update_angle >= 0)) return "update_distance and update_angle must be >= 0";
  if (!(o.odometry_check >= 0 && o.odometry_check <= 100)) return "odometry_check must be in [0, 100]";
  if (!(o.odometry_check_fraction >= 0 && o.odometry_check_fraction <= 1)) {
    return "odometry_check_fraction must be in [0, 1]";
  }
  if (!(o.odometry_check_goodness > 0 && o.odometry_check_goodness <= 1)) {
    return "odometry_check_goodness must be in (0, 1]";
  }
  if (!(o.alpha_slow > 0 && o.alpha_slow < o.alpha_fast && o.alpha_fast <= 1)) {
    return "0 < alpha_slow < alpha_fast <= 1 is required";
  }
  if (!(o.recovery_ratio > 0 && o.recovery_ratio < 1)) return "recovery_ratio must be in (0, 1)";
  if (!(o.recovery_consistency > 0 && o.recovery_consistency <= 1)) return "recovery_consistency must be in (0, 1]";
  if (o.recovery_updates < 1 || o.recovery_updates > 1000) return "recovery_updates must be in 1..1000";
  if (!(o.inject_max_fraction >= 0 && o.inject_max_fraction <= 1)) return "inject_max_fraction must be in [0, 1]";
  if (!(o.fit_min >= 0 && o.fit_min < 1)) return "fit_min must be in [0, 1)";
  if (o.global_candidates < 1 || o.global_candidates > 100) return "global_candidates must be in 1..100";
  if (static_cast<uint64_t>(o.particles_max) * o.global_candidates > 10'000'000) {
    return "particles_max * global_candidates must be at most 10000000";
  }
  if (o.threads < 1 || o.threads > 2) return "threads must be 1 or 2";
  return nullptr;
}

void validate(const MclOptions& o) {
  if (const char* why = check_options(o)) throw std::invalid_argument(why);
}

// Particles x points per update from which the likelihood is split over two threads.
constexpr std::size_t kParallelMinLookups = 100'000;
// The odometry check: scans with fewer echoes are not matched; denser ones are
// subsampled evenly to this many points (the cost of ICP grows with them). 180: every
// beam of a 180-beam scan, half of seattle's 361 (bench_mcl_real, w/mcl4: 360 cost
// seattle 0.17 ms more per update at the median, for the same lost poses and a 0.02 deg
// worse rotation RMSE; 120 missed a tenth of the stalls intel's and fhw's 180 points
// catch, and rotation RMSE rose by up to 0.2 deg).
constexpr std::size_t kCheckMinPoints = 20;
constexpr std::size_t kCheckMaxPoints = 180;
// The least heading disagreement the check acts on (rad, before odometry_check's factor).
constexpr double kCheckMinPhi = 0.05;
// How much better (mean log-likelihood per point) the scan must fit the map from the
// last estimate moved by the scans' increment than by the odometry's for the check to
// act. Real logs (bench_mcl_real, MCL_TRACE): the stalled read-outs gain 0.4-5.6; a
// rotation where the simulated office repeats, which ICP took with 99 % of the points
// paired, gained 0.04.
constexpr double kCheckMinGain = 0.25;
// The map test compares the scan's fit from the last estimate moved by either increment,
// which means something only once the particles agree on one place: while the
// estimate's position std dev is above kCheckMaxSpreadXy or its heading's above
// kCheckMaxSpreadPhi (after a global start, while the scans have not yet told the
// look-alike places apart, the mean lies between them), the check is not made.
constexpr double kCheckMaxSpreadXy = 0.5;   // m
constexpr double kCheckMaxSpreadPhi = 0.3;  // rad

struct MclFilter::Impl {
  MclOptions opt;
  // The particles live in a frame shifted by the map's origin: cell (ix, iy) covers
  // [ix, ix + 1) x [iy, iy + 1) times the resolution.
  double ox = 0.0, oy = 0.0;
  double resolution = 0.0;
  int width = 0, height = 0;
  std::vector<float> dist;        // m to the nearest occupied cell (capped later), row 0 at the bottom
  std::vector<uint8_t> occupied;  // 1: occupied cell
  std::vector<float> field;       // log-likelihood of a point in each cell
  float outside_ll = 0.0F;        // ... outside the map
  double field_max = 0.0;         // the largest log-likelihood a point can have (field and outside_ll)
  MclOptions field_opt;           // the options `field` was built with
  std::vector<std::pair<int, int>> free_cells;
  mrpt::slam::CMonteCarloLocalization2D pdf{1};
  std::vector<float> px, py;       // this scan's points (robot frame)
  std::vector<double> log_lik;     // per particle, this update
  std::vector<double> cumulative;  // resampling
  std::vector<double> weights;     // refresh_estimate(): exp(log_w) per particle
  std::vector<mrpt::math::TPose2D> drawn;
  std::vector<uint32_t> order;  // resampling: source index of each new particle
  std::unordered_set<uint64_t> bins;
  std::mt19937_64 rng;
  ComputeWorker* worker = nullptr;  // the likelihood's second thread (threads 2); not owned

  bool force_update = true;
  bool move_only = false;  // the next update moves the particles without resampling (after init_global)
  bool have_odometry = false;
  mrpt::poses::CPose2D odometry_prev;  // odometry of the previous scan
  mrpt::poses::CPose2D moved;          // odometry motion since the last filter update (jumps left out)
  MclEstimate est;                     // particles' estimate at the last update (shifted frame)
  double c_slow = 0.0, c_fast = 0.0;   // consistency averages (alpha_slow, alpha_fast)
  // The odometry check: the scans (robot frame) of the previous and of this filter
  // update, matched by ICP.
  mrpt::slam::CICP icp;
  mrpt::maps::CSimplePointsMap scans[2];
  std::size_t prev_scan = 0;  // scans[prev_scan]: the previous update's
  bool have_prev_scan = false;
  std::vector<float> scan_x, scan_y;
  bool use_scan_incr = false;  // this update: part of the particles moves by scan_incr
  // The check's "as usual": the long-term scan fit (alpha_slow) since the estimate first
  // converged after an init (0: not yet). It is w_slow while tracking from a given pose;
  // after init_global() w_slow starts at a perfect fit (recovery), which no real scan
  // keeps, and held the check off for the first 100-odd updates (seattle, seeds 3 and 8:
  // a stalled read-out there left the estimate 0.52 m off, 95 m of travel).
  double check_slow = 0.0;
  bool check_converged = false;    // this update's check found the estimate converged
  mrpt::poses::CPose2D scan_incr;  // the scan-to-scan increment (ICP)
  // Recovery: the filter has tracked as usual (not lost, estimate converged) since the
  // last init; from then on the long-term averages hold while it is lost.
  bool settled = false;

  static bool same_field(const MclOptions& a, const MclOptions& b) {
    return a.sigma_hit == b.sigma_hit && a.z_hit == b.z_hit && a.z_random == b.z_random && a.max_range == b.max_range &&
           a.max_corr_distance == b.max_corr_distance;
  }

  void build_distance(const maps::OccupancyMap& map) {
    const auto w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
    std::vector<double> grid(w * h, kFar);
    occupied.assign(w * h, 0);
    for (int iy = 0; iy < height; ++iy) {
      for (int ix = 0; ix < width; ++ix) {
        if (map.cell_state(ix, iy) == maps::CellState::kOccupied) {
          grid[static_cast<std::size_t>(iy) * w + static_cast<std::size_t>(ix)] = 0.0;
          occupied[static_cast<std::size_t>(iy) * w + static_cast<std::size_t>(ix)] = 1;
        }
      }
    }
    const std::size_t n = std::max(w, h);
    std::vector<double> f(n), d(n), z(n + 1);
    std::vector<int> v(n);
    f.resize(h);
    d.resize(h);
    for (std::size_t ix = 0; ix < w; ++ix) {  // columns
      for (std::size_t iy = 0; iy < h; ++iy) f[iy] = grid[iy * w + ix];
      edt_1d(f, d, v, z);
      for (std::size_t iy = 0; iy < h; ++iy) grid[iy * w + ix] = d[iy];
    }
    f.resize(w);
    d.resize(w);
    for (std::size_t iy = 0; iy < h; ++iy) {  // rows
      for (std::size_t ix = 0; ix < w; ++ix) f[ix] = grid[iy * w + ix];
      edt_1d(f, d, v, z);
      for (std::size_t ix = 0; ix < w; ++ix) grid[iy * w + ix] = d[ix];
    }
    dist.resize(w * h);
    for (std::size_t i = 0; i < w * h; ++i) {
      dist[i] = grid[i] >= kFar / 2 ? std::numeric_limits<float>::max()
                                    : static_cast<float>(std::sqrt(grid[i]) * resolution);
    }
  }

  void build_field() {
    const double zr = opt.z_random / opt.max_range;
    const double q = -0.5 / (opt.sigma_hit * opt.sigma_hit);
    const double maxd = opt.max_corr_distance;
    field.resize(dist.size());
    for (std::size_t i = 0; i < dist.size(); ++i) {
      const double dd = std::min<double>(dist[i], maxd);
      field[i] = static_cast<float>(std::log(zr + opt.z_hit * std::exp(q * dd * dd)));
    }
    outside_ll = static_cast<float>(std::log(zr + opt.z_hit * std::exp(q * maxd * maxd)));
    field_max = outside_ll;
    for (const float v : field) field_max = std::max(field_max, double{v});
    field_opt = opt;
  }

  void apply_options() {
    if (field.empty() || !same_field(opt, field_opt)) build_field();
    icp.options.ICP_algorithm = mrpt::slam::icpClassic;
    icp.options.thresholdDist = 1.0;  // m: pairs up to this far at first (a stalled read-out: 0.2-0.7 m short)
    icp.options.skip_cov_calculation = true;
    icp.options.skip_quality_calculation = true;
  }

  // Log-likelihood of the current points for particles [begin, end).
  void weigh(std::size_t begin, std::size_t end) {
    const std::size_t n = px.size();
    const double inv = 1.0 / resolution;
    const int w = width, h = height;
    for (std::size_t i = begin; i < end; ++i) {
      const auto& p = pdf.m_particles[i].d;
      const double c = std::cos(p.phi), s = std::sin(p.phi);
      double ll = 0.0;
      for (std::size_t k = 0; k < n; ++k) {
        const double gx = (p.x + c * px[k] - s * py[k]) * inv;
        const double gy = (p.y + s * px[k] + c * py[k]) * inv;
        if (gx >= 0.0 && gy >= 0.0 && gx < w && gy < h) {
          ll += field[static_cast<std::size_t>(static_cast<int>(gy)) * static_cast<std::size_t>(w) +
                      static_cast<std::size_t>(static_cast<int>(gx))];
        } else {
          ll += outside_ll;
        }
      }
      log_lik[i] = ll;
    }
  }

  void weigh_all() {
    const std::size_t m = pdf.m_particles.size();
    log_lik.resize(m);
    // The helper thread only when the work pays for its wake-up: below about 100 000
    // look-ups (1000 particles x 60 points: 0.1-0.2 ms on this machine) the hand-over
    // and wait cost more than half the work saves, and on a loaded machine the wait
    // for a second thread to be scheduled is what sets the update's p95 (bench/RESULTS.md).
    if (worker != nullptr && opt.threads > 1 && m >= 64 && m * px.size() >= kParallelMinLookups) {
      const std::size_t half = m / 2;
      auto second_half = [this, half, m] { weigh(half, m); };
      worker->post(second_half);
      weigh(0, half);
      if (!worker->wait()) throw std::runtime_error("MCL: the likelihood's compute worker failed");
    } else {
      weigh(0, m);
    }
    for (std::size_t i = 0; i < m; ++i) pdf.m_particles[i].log_w += opt.likelihood_power * log_lik[i];
  }

  // The motion model's std devs (x-y, heading) for an increment.
  void motion_std(const mrpt::poses::CPose2D& m, double& sxy, double& sphi) const {
    const double d = std::hypot(m.x(), m.y()), a = std::fabs(m.phi());
    sxy = std::max(opt.odom_min_std_xy, opt.odom_a1 * d + opt.odom_a2 * a);
    sphi = std::max(opt.odom_min_std_phi, opt.odom_a3 * d + opt.odom_a4 * a);
  }

  // Mean log-likelihood per point of this update's points (px, py) seen from the last
  // estimate moved by `m`.
  double fit_from_estimate(const mrpt::poses::CPose2D& m) const {
    const mrpt::poses::CPose2D p = mrpt::poses::CPose2D(est.pose.x, est.pose.y, est.pose.phi) + m;
    const double c = std::cos(p.phi()), sn = std::sin(p.phi()), inv = 1.0 / resolution;
    double ll = 0.0;
    for (std::size_t k = 0; k < px.size(); ++k) {
      const double gx = (p.x() + c * px[k] - sn * py[k]) * inv, gy = (p.y() + sn * px[k] + c * py[k]) * inv;
      ll += gx >= 0.0 && gy >= 0.0 && gx < width && gy < height
                ? field[static_cast<std::size_t>(static_cast<int>(gy)) * static_cast<std::size_t>(width) +
                        static_cast<std::size_t>(static_cast<int>(gx))]
                : outside_ll;
    }
    return px.empty() ? 0.0 : ll / static_cast<double>(px.size());
  }

  // The odometry check (MclOptions::odometry_check): this scan matched against the
  // previous update's, from the odometry increment `incr`. Sets use_scan_incr and
  // scan_incr for predict(); keeps this scan for the next update's check.
  void check_odometry(const mrpt::poses::CPose2D& incr, std::span<const float> xs, std::span<const float> ys) {
    use_scan_incr = false;
    est.odometry_disagreed = false;
    const std::size_t n = std::min(xs.size(), ys.size());
    const std::size_t want = std::min(n, kCheckMaxPoints);
    scan_x.resize(want);
    scan_y.resize(want);
    for (std::size_t k = 0; k < want; ++k) {
      const std::size_t i = want == n ? k : (k * n) / want;
      scan_x[k] = xs[i];
      scan_y[k] = ys[i];
    }
    auto& now = scans[1 - prev_scan];
    now.setAllPoints(scan_x, scan_y);
    // Trusted only while the scans fit the map as usual (the short-term fit not below
    // recovery_ratio of the long-term one since convergence, check_slow): among a crowd
    // or clutter ICP pairs people with people and its increment is the crowd's, not the
    // robot's (FHW museum).
    const bool fitting = check_slow <= 0.0 || est.w_fast >= opt.recovery_ratio * check_slow;
    const bool converged = std::sqrt(est.covariance[0] + est.covariance[4]) <= kCheckMaxSpreadXy &&
                           std::sqrt(est.covariance[8]) <= kCheckMaxSpreadPhi;
    check_converged = converged;
    // ICP only when its answer could count: the map test needs the scan to fit better
    // from the scans' increment by kCheckMinGain per point, which no increment can when
    // the fit from the odometry's is already within kCheckMinGain of the best a point can
    // have (field_max). Skipping it then changes no result (the real logs: 20-60 % of the
    // updates, all of the simulated tour's; bench/RESULTS.md).
    bool can_gain = opt.odometry_check > 0.0 && have_prev_scan && want >= kCheckMinPoints && !move_only && fitting &&
                    converged;
    double fit_odometry = 0.0;
    if (can_gain) {
      fit_odometry = fit_from_estimate(incr);
      can_gain = fit_odometry <= field_max - kCheckMinGain + 1e-9;  // (1e-9: the sums' rounding)
    }
    if (can_gain) {
      try {
        mrpt::slam::CICP::TReturnInfo info;
        const auto match = icp.Align(&scans[prev_scan], &now, incr, info);
        const mrpt::poses::CPose2D v = match->getMeanVal();
        double sxy = 0, sphi = 0;
        motion_std(v, sxy, sphi);  // the noise the odometry has if the scans' increment is the motion
        // Floors: a disagreement within the likelihood field's width (sigma_hit), or a few
        // degrees, the scan's weighting settles by itself (and ICP's own error is of that size).
        sxy = std::max(sxy, opt.sigma_hit);
        sphi = std::max(sphi, kCheckMinPhi);
        const double dxy = std::hypot(v.x() - incr.x(), v.y() - incr.y());
        const double dphi = std::fabs(wrap(v.phi() - incr.phi()));
        // Acted on only when the scan also fits the map clearly better from the last
        // estimate moved by the scans' increment than by the odometry's: ICP can settle
        // in a wrong minimum with most points paired (a rotation where the walls repeat).
        if (info.goodness >= opt.odometry_check_goodness &&
            (dxy > opt.odometry_check * sxy || dphi > opt.odometry_check * sphi) &&
            fit_from_estimate(v) - fit_odometry > kCheckMinGain) {
          use_scan_incr = opt.odometry_check_fraction > 0.0;
          scan_incr = v;
          est.odometry_disagreed = true;
          ++est.odometry_disagreements;
        }
      } catch (const std::exception&) {
        // ICP failed on this pair (degenerate scans): no check for this update.
      }
    }
    prev_scan = 1 - prev_scan;
    have_prev_scan = want >= kCheckMinPoints;
  }

  // KLD-sampling from the weighted particles, each moved by the odometry increment with
  // the motion model's noise (or, for part of them after the odometry check disagreed,
  // by the scans' increment).
  void predict(const mrpt::poses::CPose2D& incr) {
    const std::size_t m = pdf.m_particles.size();
    if (move_only) {  // the candidates of a global start: all equally likely, each kept
      move_only = false;
      std::normal_distribution<double> n01(0.0, 1.0);
      const double sxy = opt.odom_min_std_xy, sphi = opt.odom_min_std_phi;
      for (auto& p : pdf.m_particles) {
        const double dx = incr.x() + sxy * n01(rng), dy = incr.y() + sxy * n01(rng);
        const double c = std::cos(p.d.phi), s = std::sin(p.d.phi);
        p.d = mrpt::math::TPose2D(p.d.x + c * dx - s * dy, p.d.y + s * dx + c * dy,
                                  wrap(p.d.phi + incr.phi() + sphi * n01(rng)));
        p.log_w = 0.0;
      }
      return;
    }
    double max_lw = -std::numeric_limits<double>::infinity();
    for (const auto& p : pdf.m_particles) max_lw = std::max(max_lw, p.log_w);
    cumulative.resize(m);
    double sum = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      sum += std::exp(pdf.m_particles[i].log_w - max_lw);
      cumulative[i] = sum;
    }
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::normal_distribution<double> n01(0.0, 1.0);
    // The sources: a low-variance (systematic) draw of particles_max from the weighted
    // set (Thrun et al. table 4.4: one random offset, then even steps through the
    // cumulative weights), in a random order; KLD-sampling takes them from the front
    // until it has enough. A particle of weight w is drawn floor or ceil of
    // w * particles_max times, never more or fewer; with equal weights (just after an
    // init) every particle is kept once, where independent draws would leave out about
    // a third of the hypotheses of a uniform start.
    const std::size_t total = opt.particles_max;
    order.resize(total);
    {
      const double stride = sum / static_cast<double>(total);
      double r = u(rng) * stride;
      std::size_t k = 0;
      for (std::size_t j = 0; j < total; ++j, r += stride) {
        while (k + 1 < m && cumulative[k] < r) ++k;
        order[j] = static_cast<uint32_t>(k);
      }
      for (std::size_t j = total - 1; j > 0; --j) {  // Fisher-Yates
        std::uniform_int_distribution<std::size_t> pick(0, j);
        std::swap(order[j], order[pick(rng)]);
      }
    }
    double sxy = 0, sphi = 0, scan_sxy = 0, scan_sphi = 0;
    motion_std(incr, sxy, sphi);
    if (use_scan_incr) motion_std(scan_incr, scan_sxy, scan_sphi);
    bins.clear();
    drawn.clear();
    const double eps1 = 0.5 / opt.kld_epsilon;
    std::size_t nx = opt.particles_min;
    while (drawn.size() < std::max<std::size_t>(nx, opt.particles_min) && drawn.size() < total) {
      const auto& from = pdf.m_particles[order[drawn.size()]].d;
      // (The extra draw only when the check disagreed: other updates draw as before.)
      const bool by_scan = use_scan_incr && u(rng) < opt.odometry_check_fraction;
      const mrpt::poses::CPose2D& mv = by_scan ? scan_incr : incr;
      const double mxy = by_scan ? scan_sxy : sxy, mphi = by_scan ? scan_sphi : sphi;
      const double scale = u(rng) < opt.odom_outlier_fraction ? opt.odom_outlier_scale : 1.0;
      const double dx = mv.x() + scale * mxy * n01(rng), dy = mv.y() + scale * mxy * n01(rng);
      const double dphi = mv.phi() + scale * mphi * n01(rng);
      const double c = std::cos(from.phi), s = std::sin(from.phi);
      const mrpt::math::TPose2D to(from.x + c * dx - s * dy, from.y + s * dx + c * dy, wrap(from.phi + dphi));
      drawn.push_back(to);
      // KLD counts the bins of the source (the posterior the set approximates, as AMCL
      // does), not of the moved pose: the motion noise of a 1 m step spreads the
      // moved particles over hundreds of 0.1 m bins, each new bin asking for 10 more
      // particles, so the set stayed at particles_max however sure the filter was.
      const auto bx = static_cast<int64_t>(std::floor(from.x / opt.kld_bin_xy));
      const auto by = static_cast<int64_t>(std::floor(from.y / opt.kld_bin_xy));
      const auto bp = static_cast<int64_t>(std::floor(from.phi / opt.kld_bin_phi));
      const uint64_t key = (static_cast<uint64_t>(bx & 0x1FFFFF) << 42) | (static_cast<uint64_t>(by & 0x1FFFFF) << 21) |
                           static_cast<uint64_t>(bp & 0x1FFFFF);
      if (bins.insert(key).second && bins.size() > 1) {
        nx = static_cast<std::size_t>(
            std::lround(eps1 * mrpt::math::chi2inv(1.0 - opt.kld_delta, static_cast<unsigned>(bins.size() - 1))));
      }
    }
    pdf.m_particles.resize(drawn.size());
    for (std::size_t i = 0; i < drawn.size(); ++i) {
      pdf.m_particles[i].d = drawn[i];
      pdf.m_particles[i].log_w = 0.0;
    }
  }

  // After the candidates of a global start were weighed by the first scan: keep the
  // `keep` best-fitting ones, equally weighted, so that every place that fits the
  // first scan stays for the second to choose among (the likelihood of 60 points is
  // so peaked that by weight a few candidates would carry the set).
  void keep_best(std::size_t keep) {
    const std::size_t m = pdf.m_particles.size();
    if (m <= keep || log_lik.size() < m) return;
    order.resize(m);
    for (std::size_t i = 0; i < m; ++i) order[i] = static_cast<uint32_t>(i);
    std::nth_element(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(keep), order.end(),
                     [this](uint32_t a, uint32_t b) { return log_lik[a] > log_lik[b]; });
    std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(keep));
    for (std::size_t j = 0; j < keep; ++j) {
      pdf.m_particles[j].d = pdf.m_particles[order[j]].d;
      pdf.m_particles[j].log_w = 0.0;
      log_lik[j] = log_lik[order[j]];
    }
    pdf.m_particles.resize(keep);
    log_lik.resize(keep);
  }

  void random_free_pose(double& x, double& y, double& phi) {
    std::uniform_int_distribution<std::size_t> pick(0, free_cells.size() - 1);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const auto [ix, iy] = free_cells[pick(rng)];
    x = (ix + u(rng)) * resolution;
    y = (iy + u(rng)) * resolution;
    phi = wrap((u(rng) * 2.0 - 1.0) * std::numbers::pi);
  }

  // `global`: the long-term averages start at a perfect fit and consistency, so that a
  // cloud that converged to a wrong place (its fit and consistency never were good)
  // counts as lost; around a given pose they start at the first update's values.
  void reset_particles(std::size_t n, bool global) {
    pdf.m_particles.resize(n);
    for (auto& p : pdf.m_particles) p.log_w = 0.0;
    const uint64_t jumps = est.odometry_jumps, disagreements = est.odometry_disagreements;
    est = MclEstimate{};
    est.odometry_jumps = jumps;
    est.odometry_disagreements = disagreements;
    c_slow = c_fast = global ? 1.0 : 0.0;
    check_slow = 0.0;
    check_converged = false;
    settled = false;
    if (global) est.w_slow = est.w_fast = 1.0;
    force_update = true;
  }

  // A global start: particles times candidates poses uniformly over the free space.
  void spread_uniform(std::size_t particles, std::size_t candidates) {
    reset_particles(particles * candidates, true);
    move_only = candidates > 1;
    for (auto& p : pdf.m_particles) {
      double x = 0, y = 0, phi = 0;
      random_free_pose(x, y, phi);
      p.d = mrpt::math::TPose2D(x, y, phi);
    }
    refresh_estimate();
  }

  // The weights scaled so that the largest is exp(0) (what MRPT's normalizeWeights() does,
  // without its dynamic_cast per particle).
  void normalize_weights() {
    double max_lw = -std::numeric_limits<double>::infinity();
    for (const auto& p : pdf.m_particles) max_lw = std::max(max_lw, p.log_w);
    if (!std::isfinite(max_lw)) return;
    for (auto& p : pdf.m_particles) p.log_w -= max_lw;
  }

  // The estimate from the particles, in one pass over their weights: the weighted mean
  // (the heading as the direction of the weighted mean of its unit vectors, MRPT's SE(2)
  // average), the weighted covariance (heading deviations wrapped to [-pi, pi]) and the
  // effective sample size. MRPT's getCovarianceAndMean() and ESS() computed the same
  // from five exponentials per particle and a dynamic_cast per particle in ESS(): 13 %
  // of the update (perf, bench_mcl_real on intel).
  void refresh_estimate() {
    const std::size_t m = pdf.m_particles.size();
    est.particles = static_cast<uint32_t>(m);
    weights.resize(m);
    double sw = 0.0, sx = 0.0, sy = 0.0, sc = 0.0, ss = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      const auto& p = pdf.m_particles[i];
      const double w = std::exp(p.log_w);
      weights[i] = w;
      sw += w;
      sx += w * p.d.x;
      sy += w * p.d.y;
      sc += w * std::cos(p.d.phi);
      ss += w * std::sin(p.d.phi);
    }
    std::fill(std::begin(est.covariance), std::end(est.covariance), 0.0);
    if (m == 0 || !(sw > 0.0)) {
      est.pose = {};
      est.ess = 0.0F;
      return;
    }
    const double mx = sx / sw, my = sy / sw, mphi = std::atan2(ss, sc);
    double vxx = 0.0, vyy = 0.0, vpp = 0.0, vxy = 0.0, vxp = 0.0, vyp = 0.0, sq = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      const auto& p = pdf.m_particles[i].d;
      const double w = weights[i] / sw;
      const double dx = p.x - mx, dy = p.y - my, dp = wrap(p.phi - mphi);
      vxx += w * dx * dx;
      vyy += w * dy * dy;
      vpp += w * dp * dp;
      vxy += w * dx * dy;
      vxp += w * dx * dp;
      vyp += w * dy * dp;
      sq += w * w;
    }
    est.pose = {mx, my, mphi};
    if (m >= 2) {
      est.covariance[0] = vxx;
      est.covariance[4] = vyy;
      est.covariance[8] = vpp;
      est.covariance[1] = est.covariance[3] = vxy;
      est.covariance[2] = est.covariance[6] = vxp;
      est.covariance[5] = est.covariance[7] = vyp;
    }
    est.ess = sq > 0.0 ? static_cast<float>(1.0 / (static_cast<double>(m) * sq)) : 0.0F;
  }

  // The fraction of this scan's points whose beam, cast from `pose`, does not pass
  // through an occupied cell more than `tolerance` before its end. A person, a cart or
  // a crowd in front of the robot makes short readings, which are consistent with the
  // map (the beam ends in free space); the robot being somewhere else makes readings
  // that go through walls. Steps of half a cell along each beam.
  double consistency(const mrpt::math::TPose2D& pose) const {
    const std::size_t n = px.size();
    if (n == 0) return 1.0;
    const double tol = std::max(3.0 * opt.sigma_hit, 2.0 * resolution);
    const double inv = 1.0 / resolution, step = 0.5 * resolution;
    const double c = std::cos(pose.phi), s = std::sin(pose.phi);
    std::size_t good = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double r = std::hypot(double{px[k]}, double{py[k]});
      const double ux = (c * px[k] - s * py[k]) / std::max(r, 1e-9), uy = (s * px[k] + c * py[k]) / std::max(r, 1e-9);
      bool through = false;
      for (double t = 0.0; t < r - tol; t += step) {
        const double gx = (pose.x + ux * t) * inv, gy = (pose.y + uy * t) * inv;
        if (gx < 0.0 || gy < 0.0 || gx >= width || gy >= height) break;  // left the map: nothing to contradict
        if (occupied[static_cast<std::size_t>(static_cast<int>(gy)) * static_cast<std::size_t>(width) +
                     static_cast<std::size_t>(static_cast<int>(gx))] != 0) {
          through = true;
          break;
        }
      }
      good += through ? 0 : 1;
    }
    return static_cast<double>(good) / static_cast<double>(n);
  }

  // Recovery, after the particles were weighed with this scan (log_lik).
  void recover() {
    const std::size_t m = pdf.m_particles.size();
    const std::size_t points = px.size();
    if (m == 0 || points == 0) return;
    double sum = 0.0;
    for (std::size_t i = 0; i < m; ++i) sum += std::exp(log_lik[i] / static_cast<double>(points));
    est.fit = sum / static_cast<double>(m);
    // The evidence for recovery: the scan's consistency with the map at the weighted
    // mean pose (the estimate this update gives).
    mrpt::poses::CPose2D mean;
    pdf.getMean(mean);
    const double w_avg = consistency(mrpt::math::TPose2D(mean.x(), mean.y(), mean.phi()));
    est.consistency = w_avg;
    // While lost (the previous update was low), the long-term averages hold what
    // tracking gave, instead of drifting down to the lost filter's own poor fit: with
    // alpha_slow 0.01 they met it after 40-140 updates and injection stopped while the
    // estimate was still tens of metres off (bench/RESULTS.md, "Kidnapping on real
    // data"). Not after a global start until the filter once tracked as usual: there
    // the long-term averages start at a perfect fit, which no real scan keeps.
    const bool hold = settled && est.low_updates > 0;
    if (est.w_slow == 0.0) {  // first update after init_pose: start the averages at the first values
      est.w_slow = est.w_fast = est.fit;
      c_slow = c_fast = w_avg;
    } else {
      if (!hold) est.w_slow += opt.alpha_slow * (est.fit - est.w_slow);
      est.w_fast += opt.alpha_fast * (est.fit - est.w_fast);
      if (!hold) c_slow += opt.alpha_slow * (w_avg - c_slow);
      c_fast += opt.alpha_fast * (w_avg - c_fast);
    }
    if (check_slow > 0.0) {
      check_slow += opt.alpha_slow * (est.fit - check_slow);
    } else if (check_converged) {
      check_slow = est.fit;
    }
    est.injected = 0;
    // Lost: the fit dropped (w_fast / w_slow below recovery_ratio) AND the scan
    // contradicts the map at the estimate (beams through walls: c_fast / c_slow below
    // recovery_consistency), for recovery_updates updates in a row. A crowd, glass or
    // clutter lowers the fit but not the consistency (short readings end in free
    // space); one bad scan moves the fast averages by alpha_fast of its drop only.
    // Measured on bench/data/carmen (4 logs, 2 seeds, no injection): the two-sided test
    // never held for a single update, while after a kidnap in the simulator it held for
    // 20-50 updates in a row (bench/RESULTS.md).
    const double fr = est.w_fast / est.w_slow, cr = c_fast / c_slow;
    const bool low = (fr < opt.recovery_ratio && cr < opt.recovery_consistency) ||
                     (opt.fit_min > 0.0 && est.w_fast < opt.fit_min);
    est.low_updates = low ? est.low_updates + 1 : 0;
    if (!low && check_converged) settled = true;
    if (est.low_updates < opt.recovery_updates || opt.inject_max_fraction <= 0.0 || free_cells.empty()) return;
    const double p_drop = 1.0 - est.w_fast / est.w_slow;
    const double p_low = opt.fit_min > 0.0 ? 1.0 - est.w_fast / opt.fit_min : 0.0;
    const double p = std::min(opt.inject_max_fraction, std::max({0.0, p_drop, p_low}));
    const auto n = static_cast<std::size_t>(std::ceil(p * static_cast<double>(opt.particles_max)));
    if (n == 0) return;
    // After KLD-sampling every particle had the same prior weight, so its weight now is
    // power * log_lik: an injected particle gets the same, as if drawn before this scan.
    // They are added; the next KLD-sampling step brings the count back within
    // particles_min..max.
    const std::size_t first = m;
    // Each injected pose is the best fitting of global_candidates random ones (the
    // candidates all weighed by this scan, the n best kept): on a large map a uniform
    // pose rarely lands in the few tenths of a metre and degree around the true pose
    // where the scan can tell it; the scan picks where to look.
    const std::size_t cand = n * std::max<std::size_t>(1, opt.global_candidates);
    pdf.m_particles.resize(m + cand);
    log_lik.resize(m + cand);
    for (std::size_t k = first; k < m + cand; ++k) {
      double x = 0, y = 0, phi = 0;
      random_free_pose(x, y, phi);
      pdf.m_particles[k].d = mrpt::math::TPose2D(x, y, phi);
      pdf.m_particles[k].log_w = 0.0;
    }
    weigh(first, m + cand);
    if (cand > n) {  // keep the n candidates the scan fits best
      order.resize(cand);
      for (std::size_t i = 0; i < cand; ++i) order[i] = static_cast<uint32_t>(first + i);
      std::nth_element(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n), order.end(),
                       [this](uint32_t a, uint32_t b) { return log_lik[a] > log_lik[b]; });
      std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n));
      for (std::size_t j = 0; j < n; ++j) {
        pdf.m_particles[first + j].d = pdf.m_particles[order[j]].d;
        log_lik[first + j] = log_lik[order[j]];
      }
      pdf.m_particles.resize(m + n);
      log_lik.resize(m + n);
    }
    for (std::size_t k = first; k < m + n; ++k) pdf.m_particles[k].log_w = opt.likelihood_power * log_lik[k];
    est.injected = static_cast<uint32_t>(n);
    ++est.recoveries;
  }
};

MclFilter::MclFilter(const maps::OccupancyMap& map, const MclOptions& options, ComputeWorker* worker)
    : impl_(std::make_unique<Impl>()) {
  validate(options);
  Impl& s = *impl_;
  s.opt = options;
  s.worker = worker;
  if (map.width() <= 0 || map.height() <= 0 || !(map.resolution() > 0)) {
    throw std::invalid_argument("MCL: the map is empty");
  }
  if (std::fabs(map.origin_yaw()) > 1e-9) {
    throw std::invalid_argument("MCL: the map's origin yaw is " + std::to_string(map.origin_yaw()) +
                                " rad; only axis-aligned maps (yaw 0) are supported");
  }
  s.ox = map.origin_x();
  s.oy = map.origin_y();
  s.resolution = map.resolution();
  s.width = map.width();
  s.height = map.height();
  for (int iy = 0; iy < map.height(); ++iy) {
    for (int ix = 0; ix < map.width(); ++ix) {
      if (map.cell_state(ix, iy) == maps::CellState::kFree) s.free_cells.emplace_back(ix, iy);
    }
  }
  if (s.free_cells.empty()) throw std::invalid_argument("MCL: the map has no free cell");
  s.build_distance(map);
  s.rng.seed(options.seed != 0 ? options.seed
                               : static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count()));
  s.apply_options();
  // Uniform over the free space, one pose per particle: a state to start from until
  // the owner calls init_pose() or init_global() (which spreads the candidates); it
  // spares every construction the candidates' allocation and draws.
  s.spread_uniform(s.opt.particles_max, 1);
}

MclFilter::~MclFilter() = default;

const MclOptions& MclFilter::options() const noexcept { return impl_->opt; }

void MclFilter::set_options(const MclOptions& options) {
  validate(options);
  impl_->opt = options;
  impl_->apply_options();
}

void MclFilter::init_pose(const MclPose& pose, double sigma_xy, double sigma_phi) {
  Impl& s = *impl_;
  s.reset_particles(s.opt.particles_max, false);
  s.move_only = false;
  std::normal_distribution<double> nxy(0.0, std::max(sigma_xy, 0.0));
  std::normal_distribution<double> nphi(0.0, std::max(sigma_phi, 0.0));
  for (auto& p : s.pdf.m_particles) {
    p.d = mrpt::math::TPose2D(pose.x - s.ox + (sigma_xy > 0 ? nxy(s.rng) : 0.0),
                              pose.y - s.oy + (sigma_xy > 0 ? nxy(s.rng) : 0.0),
                              wrap(pose.phi + (sigma_phi > 0 ? nphi(s.rng) : 0.0)));
  }
  s.refresh_estimate();
}

void MclFilter::init_global() { impl_->spread_uniform(impl_->opt.particles_max, impl_->opt.global_candidates); }

bool MclFilter::update(const MclPose& odometry, std::span<const float> xs, std::span<const float> ys) {
  Impl& s = *impl_;
  const mrpt::poses::CPose2D odo(odometry.x, odometry.y, odometry.phi);
  if (!s.have_odometry) {
    s.odometry_prev = odo;
    s.have_odometry = true;
  }
  const mrpt::poses::CPose2D step = odo - s.odometry_prev;  // since the previous scan
  s.odometry_prev = odo;
  if (s.opt.odometry_jump > 0 && std::hypot(step.x(), step.y()) > s.opt.odometry_jump) {
    // The odometry jumped (Odometry RESET, a restarted driver): no robot moves that
    // far between two scans. Drop this one increment; the motion before it is kept.
    ++s.est.odometry_jumps;
  } else {
    s.moved = s.moved + step;
  }
  const mrpt::poses::CPose2D incr = s.moved;
  const bool moved = std::hypot(incr.x(), incr.y()) >= s.opt.update_distance ||
                     std::fabs(incr.phi()) >= s.opt.update_angle;
  const std::size_t n = std::min(xs.size(), ys.size());
  if ((!moved && !s.force_update) || n == 0) return false;

  // The observation: `beams` points spread evenly over the scan.
  const std::size_t want = s.opt.beams == 0 ? n : std::min<std::size_t>(s.opt.beams, n);
  s.px.resize(want);
  s.py.resize(want);
  for (std::size_t k = 0; k < want; ++k) {
    const std::size_t i = want == n ? k : (k * n) / want;
    s.px[k] = xs[i];
    s.py[k] = ys[i];
  }
  const bool candidates = s.move_only;
  s.check_odometry(incr, xs.first(n), ys.first(n));
  s.predict(incr);
  s.weigh_all();
  s.recover();
  if (candidates) s.keep_best(s.opt.particles_max);
  s.normalize_weights();
  s.moved = mrpt::poses::CPose2D();
  s.force_update = false;
  ++s.est.updates;
  s.refresh_estimate();
  return true;
}

MclEstimate MclFilter::estimate() const {
  const Impl& s = *impl_;
  MclEstimate e = s.est;
  // Between updates: the last estimate moved by the odometry since.
  const mrpt::poses::CPose2D mean(e.pose.x, e.pose.y, e.pose.phi);
  const mrpt::poses::CPose2D now = mean + s.moved;
  e.pose = {now.x() + s.ox, now.y() + s.oy, wrap(now.phi())};
  return e;
}

std::size_t MclFilter::sample_particles(std::span<float> x, std::span<float> y, std::span<float> phi,
                                        std::span<float> weight) const {
  const Impl& s = *impl_;
  const std::size_t cap = std::min({x.size(), y.size(), phi.size(), weight.size()});
  const std::size_t m = s.pdf.m_particles.size();
  const std::size_t n = std::min(cap, m);
  if (n == 0) return 0;
  double max_lw = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < n; ++k) max_lw = std::max(max_lw, s.pdf.m_particles[(k * m) / n].log_w);
  double sum = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const auto& p = s.pdf.m_particles[(k * m) / n];
    x[k] = static_cast<float>(p.d.x + s.ox);
    y[k] = static_cast<float>(p.d.y + s.oy);
    phi[k] = static_cast<float>(p.d.phi);
    const double w = std::exp(p.log_w - max_lw);
    weight[k] = static_cast<float>(w);
    sum += w;
  }
  for (std::size_t k = 0; k < n; ++k) weight[k] = static_cast<float>(weight[k] / sum);
  return n;
}

}  // namespace rack::mcl
