// MRPT's own Monte Carlo localisation driven directly, as its pf-localization
// application drives it: a COccupancyGridMap2D, a CSensoryFrame holding a
// CObservation2DRangeScan, a CActionRobotMovement2D (Gaussian model) from the odometry
// increment, CParticleFilter::executeOn on a CMonteCarloLocalization2D. The reference
// beside rack::mcl::MclFilter in bench_mcl and bench_mcl_real: it is given the same map,
// scans, particle count and option values (MRPT's own option structs set from
// MclOptions), so that a difference is the filter's, not the parameters'.
//
// Bench code; not RT-safe.
#pragma once

#include <mrpt/bayes/CParticleFilter.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/random/RandomGenerators.h>
#include <mrpt/slam/CMonteCarloLocalization2D.h>

#include <cmath>
#include <memory>
#include <random>

#include "mcl_sim.h"
#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"

namespace rack::bench {

class MrptReference {
 public:
  MrptReference(const rack::maps::OccupancyMap& map, const rack::mcl::MclOptions& o) : opt_(o) {
    grid_ = std::make_shared<mrpt::maps::COccupancyGridMap2D>();
    ox_ = map.origin_x();
    oy_ = map.origin_y();
    grid_->setSize(0.0F, static_cast<float>(map.width() * map.resolution()), 0.0F,
                   static_cast<float>(map.height() * map.resolution()), static_cast<float>(map.resolution()), 0.5F);
    for (int iy = 0; iy < map.height(); ++iy) {
      for (int ix = 0; ix < map.width(); ++ix) {
        const auto s = map.cell_state(ix, iy);
        grid_->setCell(
            ix, iy, s == rack::maps::CellState::kFree ? 1.0F : (s == rack::maps::CellState::kOccupied ? 0.0F : 0.5F));
      }
    }
    auto& lf = grid_->likelihoodOptions;
    lf.likelihoodMethod = mrpt::maps::COccupancyGridMap2D::lmLikelihoodField_Thrun;
    lf.LF_stdHit = static_cast<float>(o.sigma_hit);
    lf.LF_zHit = static_cast<float>(o.z_hit);
    lf.LF_zRandom = static_cast<float>(o.z_random);
    lf.LF_maxRange = static_cast<float>(o.max_range);
    lf.LF_maxCorrsDistance = static_cast<float>(o.max_corr_distance);
    lf.enableLikelihoodCache = true;
    pf_.m_options.PF_algorithm = mrpt::bayes::CParticleFilter::pfStandardProposal;
    pf_.m_options.resamplingMethod = mrpt::bayes::CParticleFilter::prMultinomial;
    pf_.m_options.adaptiveSampleSize = true;
    pf_.m_options.powFactor = o.likelihood_power;
    auto& kld = pdf_.options.KLD_params;
    kld.KLD_minSampleSize = o.particles_min;
    kld.KLD_maxSampleSize = o.particles_max;
    kld.KLD_binSize_XY = o.kld_bin_xy;
    kld.KLD_binSize_PHI = o.kld_bin_phi;
    kld.KLD_delta = o.kld_delta;
    kld.KLD_epsilon = o.kld_epsilon;
    pdf_.options.metricMap = grid_;
  }
  // MRPT takes every n-th beam of the scan (LF_decimation).
  void set_decimation(uint32_t d) { grid_->likelihoodOptions.LF_decimation = d; }

  void init_pose(const rack::test::SimPose& p, double sxy, double sphi, uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> nxy(0.0, sxy > 0 ? sxy : 1e-9), nphi(0.0, sphi > 0 ? sphi : 1e-9);
    pdf_.m_particles.resize(opt_.particles_max);
    for (auto& part : pdf_.m_particles) {
      part.d = mrpt::math::TPose2D(p.x - ox_ + nxy(rng), p.y - oy_ + nxy(rng), p.phi + nphi(rng));
      part.log_w = 0;
    }
    have_odo_ = false;
    updates_ = 0;
  }
  // Uniform over the grid's free cells (as pf-localization's init_PDF_mode 0).
  void init_global() {
    pdf_.resetUniformFreeSpace(grid_.get(), 0.7, static_cast<int>(opt_.particles_max));
    have_odo_ = false;
    updates_ = 0;
  }

  // One update from the odometry pose and the raw scan (beams evenly over a field of view
  // symmetric about the heading: start_angle = -step * (n - 1) / 2); false when gated.
  bool update(const rack::test::SimPose& odo_pose, const rack::test::SimScan& s, bool gate) {
    const mrpt::poses::CPose2D odo(odo_pose.x, odo_pose.y, odo_pose.phi);
    now_ = odo;
    if (!have_odo_) {
      last_ = odo;
      have_odo_ = true;
    }
    const mrpt::poses::CPose2D incr = odo - last_;
    if (gate && std::hypot(incr.x(), incr.y()) < opt_.update_distance && std::fabs(incr.phi()) < opt_.update_angle &&
        updates_ > 0) {
      return false;
    }
    auto obs = mrpt::obs::CObservation2DRangeScan::Create();
    obs->aperture = s.step * static_cast<float>(s.ranges.size() - 1);
    obs->rightToLeft = true;
    obs->maxRange = s.max_range;
    obs->resizeScan(s.ranges.size());
    for (std::size_t i = 0; i < s.ranges.size(); ++i) {
      obs->setScanRange(i, s.ranges[i]);
      obs->setScanRangeValidity(i, s.valid[i] != 0);
    }
    mrpt::obs::CSensoryFrame sf;
    sf.insert(obs);
    mrpt::obs::CActionRobotMovement2D move;
    move.motionModelConfiguration.modelSelection = mrpt::obs::CActionRobotMovement2D::mmGaussian;
    auto& g = move.motionModelConfiguration.gaussianModel;
    g.a1 = opt_.odom_a1;
    g.a2 = opt_.odom_a2;
    g.a3 = opt_.odom_a3;
    g.a4 = opt_.odom_a4;
    g.minStdXY = opt_.odom_min_std_xy;
    g.minStdPHI = opt_.odom_min_std_phi;
    move.computeFromOdometry(incr, move.motionModelConfiguration);
    mrpt::obs::CActionCollection actions;
    actions.insert(move);
    pf_.executeOn(pdf_, &actions, &sf);
    last_ = odo;
    ++updates_;
    return true;
  }
  // The particles' mean at the last update composed with the odometry since (as
  // MclFilter::estimate()).
  [[nodiscard]] rack::test::SimPose estimate() const {
    mrpt::poses::CPose2D m;
    pdf_.getMean(m);
    const mrpt::poses::CPose2D moved = have_odo_ ? m + (now_ - last_) : m;
    return {moved.x() + ox_, moved.y() + oy_, moved.phi()};
  }
  [[nodiscard]] std::size_t particles() const { return pdf_.m_particles.size(); }

 private:
  rack::mcl::MclOptions opt_;
  std::shared_ptr<mrpt::maps::COccupancyGridMap2D> grid_;
  double ox_ = 0, oy_ = 0;
  mrpt::slam::CMonteCarloLocalization2D pdf_{1};
  mrpt::bayes::CParticleFilter pf_;
  mrpt::poses::CPose2D last_, now_;
  bool have_odo_ = false;
  uint64_t updates_ = 0;
};

}  // namespace rack::bench
