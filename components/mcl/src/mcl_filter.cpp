#include "rack/mcl/mcl_filter.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mrpt/bayes/CParticleFilter.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/random/RandomGenerators.h>
#include <mrpt/slam/CMonteCarloLocalization2D.h>
#include <mutex>
#include <numbers>
#include <random>
#include <vector>

namespace rack::mcl {

namespace {

// MRPT's motion sampler and resampler draw from mrpt::random::getRandomGenerator(),
// one per process and not thread-safe: filters in one process take turns.
std::mutex& mrpt_random_lock() {
  static std::mutex m;
  return m;
}

double wrap(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

// CMonteCarloLocalization2D with the observation model evaluated on a point set that
// the caller prepared (robot-frame scan points) instead of a CObservation: the same
// likelihood-field function MRPT applies to a laser scan's points
// (COccupancyGridMap2D::computeLikelihoodField_Thrun), without requiring a regular
// beam layout. It records each particle's log-likelihood for the recovery statistics.
class PointsMcl final : public mrpt::slam::CMonteCarloLocalization2D {
 public:
  explicit PointsMcl(std::size_t n) : CMonteCarloLocalization2D(n) {}

  double PF_SLAM_computeObservationLikelihoodForParticle(
      const mrpt::bayes::CParticleFilter::TParticleFilterOptions& /*pf_options*/, const size_t index,
      const mrpt::obs::CSensoryFrame& /*observation*/, const mrpt::poses::CPose3D& x) const override {
    const mrpt::poses::CPose2D pose(x);
    const double ll = grid->computeLikelihoodField_Thrun(points, &pose);
    if (index < log_lik.size()) log_lik[index] = ll;
    return ll;
  }

  const mrpt::maps::COccupancyGridMap2D* grid = nullptr;
  const mrpt::maps::CSimplePointsMap* points = nullptr;
  mutable std::vector<double> log_lik;  // per particle, at the last update
};

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
  if (!(o.update_distance >= 0 && o.update_angle >= 0)) return "update_distance and update_angle must be >= 0";
  if (!(o.alpha_slow > 0 && o.alpha_slow < o.alpha_fast && o.alpha_fast <= 1)) {
    return "0 < alpha_slow < alpha_fast <= 1 is required";
  }
  if (!(o.inject_max_fraction >= 0 && o.inject_max_fraction <= 1)) return "inject_max_fraction must be in [0, 1]";
  if (!(o.fit_min >= 0 && o.fit_min < 1)) return "fit_min must be in [0, 1)";
  return nullptr;
}

void validate(const MclOptions& o) {
  if (const char* why = check_options(o)) throw std::invalid_argument(why);
}

struct MclFilter::Impl {
  MclOptions opt;
  // MRPT works in a frame shifted by the map's origin, so that the grid's limits are
  // exact multiples of the resolution (MRPT rounds them) and cells line up with the
  // OccupancyMap's.
  double ox = 0.0, oy = 0.0;
  double resolution = 0.0;
  // The grid is rebuilt when a likelihood-field option changes: MRPT caches the field
  // per cell (enableLikelihoodCache) and offers no way to invalidate that cache.
  std::shared_ptr<mrpt::maps::COccupancyGridMap2D> grid;
  int width = 0, height = 0;
  std::vector<float> cells;  // MRPT's values (probability of FREE), row 0 at the bottom
  MclOptions grid_opt;       // the likelihood-field options the grid was built with
  std::vector<std::pair<int, int>> free_cells;
  PointsMcl pdf{1};
  mrpt::bayes::CParticleFilter pf;
  mrpt::maps::CSimplePointsMap points;
  std::mt19937_64 rng;

  bool force_update = true;
  bool have_odometry = false;
  mrpt::poses::CPose2D odometry_at_update;  // odometry pose of the last filter update
  mrpt::poses::CPose2D odometry_now;
  MclEstimate est;                          // particles' estimate at the last update (shifted frame)

  static bool same_field(const MclOptions& a, const MclOptions& b) {
    return a.sigma_hit == b.sigma_hit && a.z_hit == b.z_hit && a.z_random == b.z_random &&
           a.max_range == b.max_range && a.max_corr_distance == b.max_corr_distance;
  }

  void build_grid() {
    grid = std::make_shared<mrpt::maps::COccupancyGridMap2D>();
    const auto res = static_cast<float>(resolution);
    grid->setSize(0.0F, static_cast<float>(width * resolution), 0.0F, static_cast<float>(height * resolution), res,
                  0.5F);
    const int w = std::min<int>(width, static_cast<int>(grid->getSizeX()));
    const int h = std::min<int>(height, static_cast<int>(grid->getSizeY()));
    for (int iy = 0; iy < h; ++iy) {
      for (int ix = 0; ix < w; ++ix) grid->setCell(ix, iy, cells[static_cast<std::size_t>(iy * width + ix)]);
    }
    auto& lf = grid->likelihoodOptions;
    lf.likelihoodMethod = mrpt::maps::COccupancyGridMap2D::lmLikelihoodField_Thrun;
    lf.LF_stdHit = static_cast<float>(opt.sigma_hit);
    lf.LF_zHit = static_cast<float>(opt.z_hit);
    lf.LF_zRandom = static_cast<float>(opt.z_random);
    lf.LF_maxRange = static_cast<float>(opt.max_range);
    lf.LF_maxCorrsDistance = static_cast<float>(opt.max_corr_distance);
    lf.LF_decimation = 1;  // points are subsampled here (`beams`)
    lf.enableLikelihoodCache = true;
    grid_opt = opt;
  }

  void apply_options() {
    if (!grid || !same_field(opt, grid_opt)) build_grid();
    pf.m_options.PF_algorithm = mrpt::bayes::CParticleFilter::pfStandardProposal;
    pf.m_options.resamplingMethod = mrpt::bayes::CParticleFilter::prMultinomial;  // MRPT requires it with KLD (dynamic count)
    pf.m_options.adaptiveSampleSize = true;
    pf.m_options.powFactor = opt.likelihood_power;
    pf.m_options.BETA = 0.5;
    auto& kld = pdf.options.KLD_params;
    kld.KLD_minSampleSize = opt.particles_min;
    kld.KLD_maxSampleSize = opt.particles_max;
    kld.KLD_binSize_XY = opt.kld_bin_xy;
    kld.KLD_binSize_PHI = opt.kld_bin_phi;
    kld.KLD_delta = opt.kld_delta;
    kld.KLD_epsilon = opt.kld_epsilon;
    pdf.options.metricMap = grid;
    pdf.grid = grid.get();
    pdf.points = &points;
    pdf.log_lik.assign(opt.particles_max + 1, 0.0);  // KLD never draws more than particles_max
  }

  void random_free_pose(double& x, double& y, double& phi) {
    std::uniform_int_distribution<std::size_t> pick(0, free_cells.size() - 1);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const auto [ix, iy] = free_cells[pick(rng)];
    x = (ix + u(rng)) * resolution;
    y = (iy + u(rng)) * resolution;
    phi = wrap((u(rng) * 2.0 - 1.0) * std::numbers::pi);
  }

  void reset_particles(std::size_t n) {
    pdf.m_particles.resize(n);
    for (auto& p : pdf.m_particles) p.log_w = 0.0;
    const uint64_t jumps = est.odometry_jumps;
    est = MclEstimate{};
    est.odometry_jumps = jumps;
    force_update = true;
  }

  void refresh_estimate() {
    const auto [cov, mean] = pdf.getCovarianceAndMean();
    est.pose = {mean.x(), mean.y(), mean.phi()};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) est.covariance[r * 3 + c] = cov(r, c);
    }
    est.particles = static_cast<uint32_t>(pdf.m_particles.size());
    est.ess = est.particles > 0 ? static_cast<float>(pdf.ESS()) : 0.0F;
  }

  // Augmented MCL's injection, after the filter weighed the particles with this scan.
  void inject(std::size_t used_points) {
    const std::size_t m = pdf.m_particles.size();
    if (m == 0 || used_points == 0) return;
    double sum = 0.0;
    for (std::size_t i = 0; i < m; ++i) sum += std::exp(pdf.log_lik[i] / static_cast<double>(used_points));
    const double w_avg = sum / static_cast<double>(m);
    est.fit = w_avg;
    if (est.w_slow == 0.0) {  // first update: start both averages at the first fit
      est.w_slow = est.w_fast = w_avg;
    } else {
      est.w_slow += opt.alpha_slow * (w_avg - est.w_slow);
      est.w_fast += opt.alpha_fast * (w_avg - est.w_fast);
    }
    est.injected = 0;
    // Thrun's term reacts to a sudden drop of the fit (kidnapping); the fit_min term to
    // a filter that converged to a wrong place, whose fit never was good (after a
    // global start the long-term average has no good fit to compare with).
    const double p_drop = 1.0 - est.w_fast / est.w_slow;
    const double p_low = opt.fit_min > 0.0 ? 1.0 - est.w_fast / opt.fit_min : 0.0;
    const double p = std::min(opt.inject_max_fraction, std::max({0.0, p_drop, p_low}));
    const auto n = static_cast<std::size_t>(std::floor(p * static_cast<double>(opt.particles_max)));
    if (n == 0 || free_cells.empty()) return;
    // After KLD-sampling every particle had the same prior weight, so its weight now is
    // power * log_lik + c with one c for all: an injected particle gets the same, as if
    // it had been drawn before this scan. Injected particles are added (the next
    // KLD-sampling step brings the count back within particles_min..max).
    const double c = pdf.m_particles[0].log_w - opt.likelihood_power * pdf.log_lik[0];
    for (std::size_t k = 0; k < n; ++k) {
      double x = 0, y = 0, phi = 0;
      random_free_pose(x, y, phi);
      const mrpt::poses::CPose2D pose(x, y, phi);
      const double ll = grid->computeLikelihoodField_Thrun(&points, &pose);
      auto& part = pdf.m_particles.emplace_back();
      part.d = mrpt::math::TPose2D(x, y, phi);
      part.log_w = opt.likelihood_power * ll + c;
    }
    pdf.normalizeWeights();
    est.injected = static_cast<uint32_t>(n);
  }
};

MclFilter::MclFilter(const maps::OccupancyMap& map, const MclOptions& options) : impl_(std::make_unique<Impl>()) {
  validate(options);
  Impl& s = *impl_;
  s.opt = options;
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
  s.cells.assign(static_cast<std::size_t>(map.width()) * static_cast<std::size_t>(map.height()), 0.5F);
  for (int iy = 0; iy < map.height(); ++iy) {
    for (int ix = 0; ix < map.width(); ++ix) {
      float& c = s.cells[static_cast<std::size_t>(iy * map.width() + ix)];
      switch (map.cell_state(ix, iy)) {
        case maps::CellState::kFree:  // MRPT stores the probability of a cell being FREE
          c = 1.0F;
          s.free_cells.emplace_back(ix, iy);
          break;
        case maps::CellState::kOccupied: c = 0.0F; break;
        case maps::CellState::kUnknown: c = 0.5F; break;
      }
    }
  }
  if (s.free_cells.empty()) throw std::invalid_argument("MCL: the map has no free cell");
  s.rng.seed(options.seed != 0 ? options.seed
                               : static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count()));
  {
    std::lock_guard lock(mrpt_random_lock());
    if (options.seed != 0) mrpt::random::getRandomGenerator().randomize(static_cast<uint32_t>(options.seed));
  }
  s.apply_options();
  init_global();
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
  s.reset_particles(s.opt.particles_max);
  std::normal_distribution<double> nxy(0.0, std::max(sigma_xy, 0.0));
  std::normal_distribution<double> nphi(0.0, std::max(sigma_phi, 0.0));
  for (auto& p : s.pdf.m_particles) {
    p.d = mrpt::math::TPose2D(pose.x - s.ox + (sigma_xy > 0 ? nxy(s.rng) : 0.0),
                              pose.y - s.oy + (sigma_xy > 0 ? nxy(s.rng) : 0.0),
                              wrap(pose.phi + (sigma_phi > 0 ? nphi(s.rng) : 0.0)));
  }
  s.refresh_estimate();
}

void MclFilter::init_global() {
  Impl& s = *impl_;
  s.reset_particles(s.opt.particles_max);
  for (auto& p : s.pdf.m_particles) {
    double x = 0, y = 0, phi = 0;
    s.random_free_pose(x, y, phi);
    p.d = mrpt::math::TPose2D(x, y, phi);
  }
  s.refresh_estimate();
}

bool MclFilter::update(const MclPose& odometry, std::span<const float> xs, std::span<const float> ys) {
  Impl& s = *impl_;
  const mrpt::poses::CPose2D odo(odometry.x, odometry.y, odometry.phi);
  if (!s.have_odometry) {
    s.odometry_at_update = odo;
    s.have_odometry = true;
  }
  mrpt::poses::CPose2D incr = odo - s.odometry_at_update;  // in the frame of the last update
  if (s.opt.odometry_jump > 0 && std::hypot(incr.x(), incr.y()) > s.opt.odometry_jump) {
    // The odometry jumped (Odometry RESET, a restarted driver): no robot moves that
    // far between two scans. Re-anchor on the new odometry; the particles stay.
    ++s.est.odometry_jumps;
    s.odometry_at_update = odo;
    incr = mrpt::poses::CPose2D();
  }
  s.odometry_now = odo;
  const bool moved = std::hypot(incr.x(), incr.y()) >= s.opt.update_distance ||
                     std::fabs(incr.phi()) >= s.opt.update_angle;
  const std::size_t n = std::min(xs.size(), ys.size());
  if ((!moved && !s.force_update) || n == 0) return false;

  // The observation: `beams` points spread evenly over the scan.
  s.points.clear();
  const std::size_t want = s.opt.beams == 0 ? n : std::min<std::size_t>(s.opt.beams, n);
  s.points.reserve(want);
  for (std::size_t k = 0; k < want; ++k) {
    const std::size_t i = want == n ? k : (k * n) / want;
    s.points.insertPointFast(xs[i], ys[i], 0.0F);
  }

  mrpt::obs::CActionRobotMovement2D move;
  move.motionModelConfiguration.modelSelection = mrpt::obs::CActionRobotMovement2D::mmGaussian;
  auto& g = move.motionModelConfiguration.gaussianModel;
  g.a1 = s.opt.odom_a1;
  g.a2 = s.opt.odom_a2;
  g.a3 = s.opt.odom_a3;
  g.a4 = s.opt.odom_a4;
  g.minStdXY = s.opt.odom_min_std_xy;
  g.minStdPHI = s.opt.odom_min_std_phi;
  move.computeFromOdometry(incr, move.motionModelConfiguration);
  mrpt::obs::CActionCollection actions;
  actions.insert(move);
  const mrpt::obs::CSensoryFrame frame;  // the points above are the observation

  {
    std::lock_guard lock(mrpt_random_lock());
    s.pf.executeOn(s.pdf, &actions, &frame);
    s.inject(want);
  }
  s.odometry_at_update = odo;
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
  const mrpt::poses::CPose2D moved = s.have_odometry ? mean + (s.odometry_now - s.odometry_at_update) : mean;
  e.pose = {moved.x() + s.ox, moved.y() + s.oy, wrap(moved.phi())};
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
