// bench_mcl: Monte Carlo localisation (rack::mcl::MclFilter on MRPT) beside MRPT's own
// CMonteCarloLocalization2D driven directly, on the same scans, map and options, in
// the same run; accuracy against ground truth; global localisation and kidnapping
// with and without the random injection; and the wake-up latency of a 1 kHz
// SCHED_FIFO control task with and without MCL running beside it.
//
// Dataset: the scripted robot of tests/unit/mcl_sim.h drives a tour of the shipped
// office map (configs/maps/office.yaml); scans are ray-cast from the true pose with
// 1 cm range noise (181 beams over 270 degrees, 10 m), odometry has 2 % noise. Debian's
// mrpt-common ships no laser rawlog with ground truth (see bench/RESULTS.md), so the
// accuracy figures come from this simulated run.
//
//   bench_mcl [--quick] [--no-latency] [--latency-seconds S] [--parts LIST]
//             [--particles N,N,...] [--scans N] [--threads 1|2] [--json FILE]
//     --parts: any of update,accuracy,recovery,latency (default all); --particles and
//     --scans set the update-time part (default 250..4000, 400 scans per round);
//     --json writes the update-time figures for bench/run (bench/results_md.py).
//   bench_mcl --write-carmen FILE [--steps N] [--beams B]   (the example log in configs/logs/)
//
// Not RT code. The latency part needs root (SCHED_FIFO); without it that part is skipped.
#include <sched.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <mrpt/bayes/CParticleFilter.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/random/RandomGenerators.h>
#include <mrpt/slam/CMonteCarloLocalization2D.h>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "mcl_reference.h"
#include "mcl_worker.h"
#include "mcl_sim.h"
#include "rack/components/builtin.h"
#include "rack/core/data_component.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/core/registry.h"
#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/rt/memory.h"

namespace {

using rack::bench::MrptReference;
using rack::bench::Percentiles;
using rack::mcl::MclFilter;
using rack::mcl::MclOptions;
using rack::test::ScriptedRobot;
using rack::test::SimConfig;
using rack::test::SimPose;
using rack::test::SimScan;

struct Step {
  SimPose odometry, truth;
  SimScan scan;
};

const std::vector<std::pair<double, double>> kTour = {{2.0, 8.0},   {9.6, 8.0},  {9.6, 4.0},  {11.0, 3.0},
                                                      {9.6, 4.0},   {9.6, 8.0},  {18.0, 8.0}, {19.6, 11.5},
                                                      {19.6, 13.5}, {19.6, 8.0}, {4.0, 8.0}};

std::vector<Step> record(const rack::maps::OccupancyMap& map, uint64_t seed,
                         const std::vector<std::pair<double, double>>& tour = kTour) {
  ScriptedRobot robot(map, SimConfig{}, seed);
  robot.place({tour[0].first, tour[0].second, 0.0});
  std::vector<Step> steps;
  for (std::size_t w = 1; w < tour.size(); ++w) {
    for (int guard = 0; guard < 5000 && !robot.step_towards(tour[w].first, tour[w].second); ++guard) {
      steps.push_back({robot.odometry(), robot.truth(), robot.scan()});
    }
  }
  return steps;
}

int64_t now_ns() { return rack::rt::monotonic_ns(); }

uint32_t g_threads = 2;  // --threads: MclFilter's likelihood threads in the update-time part

struct Dist {
  std::size_t n = 0;
  double p50 = 0, p95 = 0, p99 = 0, max = 0;  // ms
};
Dist dist_of(std::vector<int64_t> v) {
  Dist d;
  if (v.empty()) return d;
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) { return static_cast<double>(v[rack::bench::nearest_rank(q, v.size()) - 1]) / 1e6; };
  d.n = v.size();
  d.p50 = at(0.50);
  d.p95 = at(0.95);
  d.p99 = at(0.99);
  d.max = static_cast<double>(v.back()) / 1e6;
  return d;
}

// ---- 1. update time against particle count, rack vs MRPT ------------------------
struct UpdateResult {
  uint32_t particles = 0, points = 0, decimation = 1;  // points 0: every echo
  Percentiles rack, mrpt;
  double median_pair_ratio = 0;
};

std::vector<UpdateResult> bench_update_time(const rack::maps::OccupancyMap& map, const std::vector<Step>& steps,
                                            bool quick, std::vector<uint32_t> particles, std::size_t scans) {
  std::vector<UpdateResult> results;
  const std::size_t n_steps = std::min<std::size_t>(steps.size(), scans > 0 ? scans : (quick ? 150 : 400));
  std::printf("\n### Update time per scan\n\n");
  std::printf(
      "Every scan updates (no gating), %zu scans per round, 2 rounds; fixed particle count (KLD min = max). "
      "Both filters run in lockstep, one after the other on each scan (order alternating per scan), so that "
      "both see the same machine load. Same map, options and scans; rack's filter gets the echoes as "
      "robot-frame points (as Scan2D delivers them), MRPT's the same beams as a CObservation2DRangeScan "
      "(which MRPT turns into points itself, with its own filtering; rack uses every echo). Time: CLOCK_MONOTONIC "
      "around one update call, SCHED_OTHER.\n\n",
      n_steps);
  std::printf(
      "| particles | side | updates | p50 ms | p95 ms | p99 ms | max ms | p50 ratio | p95 ratio | median per-scan ratio |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
  struct Config {
    uint32_t n, beams, decimation;
  };
  std::vector<Config> configs;
  if (particles.empty()) {
    particles = quick ? std::vector<uint32_t>{250, 1000, 4000} : std::vector<uint32_t>{250, 500, 1000, 2000, 4000};
  }
  for (uint32_t n : particles) {
    configs.push_back({n, 0, 1});  // every echo on both sides (MRPT: LF_decimation 1)
  }
  // MCL's default: 60 points per scan; MRPT: every 3rd of the 181 beams.
  configs.push_back({1000, 60, 3});
  for (const Config& c : configs) {
    const uint32_t n = c.n;
    MclOptions o;
    o.particles_min = n;
    o.particles_max = n;
    o.update_distance = 0.0;
    o.update_angle = 0.0;
    o.beams = c.beams;
    o.seed = 1;
    o.threads = g_threads;
    std::vector<int64_t> rack_t, ref_t;
    std::vector<double> pair_ratio;
    for (int round = 0; round < 2; ++round) {
      MclFilter f(map, o, rack::bench::mcl_compute_worker());
      f.init_pose({steps[0].truth.x, steps[0].truth.y, steps[0].truth.phi}, 0.1, 0.05);
      MrptReference ref(map, o);
      ref.set_decimation(c.decimation);
      ref.init_pose(steps[0].truth, 0.1, 0.05, 1);
      // Lockstep: both filters take the same scan one after the other (order alternating
      // per scan), so both see the same load on this shared machine.
      for (std::size_t i = 0; i < n_steps; ++i) {
        const auto& s = steps[i];
        int64_t tr = 0, tm = 0;
        for (int k = 0; k < 2; ++k) {
          if ((k == 0) == (i % 2 == 0)) {
            const int64_t t0 = now_ns();
            (void)f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
            tr = now_ns() - t0;
          } else {
            const int64_t t0 = now_ns();
            (void)ref.update(s.odometry, s.scan, false);
            tm = now_ns() - t0;
          }
        }
        rack_t.push_back(tr);
        ref_t.push_back(tm);
        pair_ratio.push_back(static_cast<double>(tr) / static_cast<double>(tm));
      }
    }
    std::sort(pair_ratio.begin(), pair_ratio.end());
    const double median_pair = pair_ratio[pair_ratio.size() / 2];
    UpdateResult res;
    res.particles = n;
    res.points = c.beams;
    res.decimation = c.decimation;
    res.median_pair_ratio = median_pair;
    {
      auto ra = rack_t, rb = ref_t;
      res.rack = rack::bench::percentiles_of(ra);
      res.mrpt = rack::bench::percentiles_of(rb);
    }
    results.push_back(res);
    const Dist a = dist_of(rack_t), b = dist_of(ref_t);
    char label[64];
    if (c.beams == 0) std::snprintf(label, sizeof label, "%u", n);
    else std::snprintf(label, sizeof label, "%u, %u points (MRPT: 1 in %u beams)", n, c.beams, c.decimation);
    std::printf("| %s | **rack MclFilter** | %zu | %.3f | %.3f | %.3f | %.3f | **%.2fx** | **%.2fx** | **%.2fx** |\n",
                label, a.n, a.p50, a.p95, a.p99, a.max, a.p50 / b.p50, a.p95 / b.p95, median_pair);
    std::printf("| %s | MRPT CMonteCarloLocalization2D (reference) | %zu | %.3f | %.3f | %.3f | %.3f | 1 | 1 | 1 |\n",
                label, b.n, b.p50, b.p95, b.p99, b.max);
    std::fflush(stdout);
  }
  return results;
}

// ---- 2. accuracy against ground truth ---------------------------------------------
struct Accuracy {
  double ate = 0;      // m, RMS position error over the filter updates
  double ate_phi = 0;  // rad, RMS heading error
  double rpe_t = 0;    // translational error per metre travelled (ratio), 1 m segments, RMS
  double rpe_r = 0;    // rad per metre, RMS
  double max_err = 0;  // m
  std::size_t n = 0;
};

Accuracy accuracy_of(const std::vector<SimPose>& est, const std::vector<SimPose>& truth) {
  Accuracy a;
  double se = 0, sp = 0;
  for (std::size_t i = 0; i < est.size(); ++i) {
    const double e = std::hypot(est[i].x - truth[i].x, est[i].y - truth[i].y);
    se += e * e;
    sp += std::pow(rack::test::angle_diff(est[i].phi, truth[i].phi), 2);
    a.max_err = std::max(a.max_err, e);
  }
  a.n = est.size();
  a.ate = std::sqrt(se / static_cast<double>(std::max<std::size_t>(1, a.n)));
  a.ate_phi = std::sqrt(sp / static_cast<double>(std::max<std::size_t>(1, a.n)));
  // Relative error over segments of >= 1 m of travel: the estimate's motion against the
  // truth's, both expressed in the segment start's frame.
  double st = 0, sr = 0;
  std::size_t m = 0;
  std::size_t j = 0;
  double run = 0;
  for (std::size_t i = 0; i + 1 < truth.size(); ++i) {
    run = 0;
    for (j = i + 1; j < truth.size(); ++j) {
      run += std::hypot(truth[j].x - truth[j - 1].x, truth[j].y - truth[j - 1].y);
      if (run >= 1.0) break;
    }
    if (j >= truth.size()) break;
    const mrpt::poses::CPose2D t0(truth[i].x, truth[i].y, truth[i].phi), t1(truth[j].x, truth[j].y, truth[j].phi);
    const mrpt::poses::CPose2D e0(est[i].x, est[i].y, est[i].phi), e1(est[j].x, est[j].y, est[j].phi);
    const mrpt::poses::CPose2D dt = t1 - t0, de = e1 - e0;
    const mrpt::poses::CPose2D err = de - dt;
    st += std::pow(std::hypot(err.x(), err.y()) / run, 2);
    sr += std::pow(err.phi() / run, 2);
    ++m;
  }
  a.rpe_t = std::sqrt(st / static_cast<double>(std::max<std::size_t>(1, m)));
  a.rpe_r = std::sqrt(sr / static_cast<double>(std::max<std::size_t>(1, m)));
  return a;
}

void bench_accuracy(const rack::maps::OccupancyMap& map, bool quick) {
  std::printf("\n### Accuracy on the simulated tour (ground truth)\n\n");
  const int seeds = quick ? 2 : 5;
  std::printf(
      "Tour of the office map (%zu waypoints, about 60 m), default MCL options (particles 100..2000, "
      "update after 0.10 m or 0.10 rad, 60 beams), start pose known within 0.2 m / 0.1 rad; seeds 1..%d. "
      "ATE: RMS of the position (heading) error at every filter update; RPE: RMS over 1 m segments of the "
      "relative-motion error per metre. Odometry alone (aligned at the start) and MRPT's own filter "
      "(same options, every echo, same gating) beside it.\n\n",
      kTour.size(), seeds);
  std::printf(
      "| side | updates | ATE m | ATE heading deg | max error m | RPE %% | RPE deg/m |\n|---|---|---|---|---|---|---|\n");
  std::vector<SimPose> e_rack, e_ref, e_odo, t_all;
  for (int seed = 1; seed <= seeds; ++seed) {
    const auto steps = record(map, static_cast<uint64_t>(seed));
    MclOptions o;
    o.seed = static_cast<uint64_t>(seed);
    MclFilter f(map, o, rack::bench::mcl_compute_worker());
    f.init_pose({steps[0].truth.x + 0.1, steps[0].truth.y - 0.1, steps[0].truth.phi + 0.05}, 0.2, 0.1);
    mrpt::random::getRandomGenerator().randomize(static_cast<uint32_t>(seed));
    MclOptions ro = o;
    MrptReference ref(map, ro);
    ref.set_decimation(1);
    ref.init_pose({steps[0].truth.x + 0.1, steps[0].truth.y - 0.1, steps[0].truth.phi + 0.05}, 0.2, 0.1,
                  static_cast<uint64_t>(seed));
    const mrpt::poses::CPose2D start(steps[0].truth.x, steps[0].truth.y, steps[0].truth.phi);
    const mrpt::poses::CPose2D odo0(steps[0].odometry.x, steps[0].odometry.y, steps[0].odometry.phi);
    for (const auto& s : steps) {
      const bool ran = f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
      (void)ref.update(s.odometry, s.scan, true);
      if (!ran) continue;
      const auto e = f.estimate();
      e_rack.push_back({e.pose.x, e.pose.y, e.pose.phi});
      e_ref.push_back(ref.estimate());
      const mrpt::poses::CPose2D od = start + (mrpt::poses::CPose2D(s.odometry.x, s.odometry.y, s.odometry.phi) - odo0);
      e_odo.push_back({od.x(), od.y(), od.phi()});
      t_all.push_back(s.truth);
    }
  }
  const auto row = [&](const char* name, const std::vector<SimPose>& e) {
    const Accuracy a = accuracy_of(e, t_all);
    std::printf("| %s | %zu | %.4f | %.2f | %.3f | %.2f | %.3f |\n", name, a.n, a.ate,
                a.ate_phi * 180 / std::numbers::pi, a.max_err, a.rpe_t * 100, a.rpe_r * 180 / std::numbers::pi);
  };
  row("**rack MclFilter**", e_rack);
  row("MRPT CMonteCarloLocalization2D (reference)", e_ref);
  row("odometry alone", e_odo);
  std::fflush(stdout);
}

// ---- 3. global localisation and kidnapping, with and without injection -----------
double travel_to_converge(MclFilter& f, const std::vector<Step>& steps, std::size_t from, double tol) {
  double travelled = 0, at = 1e9;
  for (std::size_t i = from; i < steps.size(); ++i) {
    const auto& s = steps[i];
    if (i > from) travelled += std::hypot(s.truth.x - steps[i - 1].truth.x, s.truth.y - steps[i - 1].truth.y);
    if (!f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys)) continue;
    const auto e = f.estimate();
    const bool good = std::hypot(e.pose.x - s.truth.x, e.pose.y - s.truth.y) < tol;
    if (!good) at = 1e9;
    else if (at > 1e8) at = travelled;
  }
  return at;
}

void bench_recovery(const rack::maps::OccupancyMap& map, bool quick) {
  const int seeds = quick ? 8 : 20;
  std::printf("\n### Global localisation and kidnapping (travel until the estimate is within 0.3 m and stays)\n\n");
  std::printf(
      "Seeds 11..%d (global) and 21..%d (kidnap); particles 300..8000 (global) and 200..3000 (kidnap); "
      "'no injection' is the same filter with inject_max_fraction 0 (no recovery, as MRPT's filter).\n\n",
      10 + seeds, 20 + seeds);
  std::printf(
      "| case | side | within 5 m | within 15 m | within 40 m | never | median m |\n|---|---|---|---|---|---|---|\n");
  for (int kind = 0; kind < 2; ++kind) {
    for (int inj = 1; inj >= 0; --inj) {
      std::vector<double> at;
      for (int k = 0; k < seeds; ++k) {
        const uint64_t seed = static_cast<uint64_t>((kind == 0 ? 11 : 21) + k);
        MclOptions o;
        o.seed = seed;
        if (inj == 0) o.inject_max_fraction = 0.0;
        if (kind == 0) {
          o.particles_min = 300;
          o.particles_max = 8000;
          const auto steps = record(map, seed);
          MclFilter f(map, o, rack::bench::mcl_compute_worker());
          f.init_global();
          at.push_back(travel_to_converge(f, steps, 0, 0.3));
        } else {
          o.particles_min = 200;
          o.particles_max = 3000;
          // Track from (2, 8) to (8, 8), then the robot is carried to (15.6, 8).
          const auto before = record(map, seed, {{2.0, 8.0}, {8.0, 8.0}});
          auto after = record(map, seed + 1000,
                              {{15.6, 8.0},
                               {21.0, 8.0},
                               {21.1, 4.0},
                               {21.1, 8.0},
                               {14.0, 8.0},
                               {13.6, 11.5},
                               {13.6, 13.5},
                               {13.6, 8.0},
                               {4.0, 8.0}});
          // The odometry continues from where it was: shift the second part's odometry.
          const mrpt::poses::CPose2D last_odo(before.back().odometry.x, before.back().odometry.y,
                                              before.back().odometry.phi);
          const mrpt::poses::CPose2D first_odo(after.front().odometry.x, after.front().odometry.y,
                                               after.front().odometry.phi);
          for (auto& s : after) {
            const mrpt::poses::CPose2D p = last_odo +
                                           (mrpt::poses::CPose2D(s.odometry.x, s.odometry.y, s.odometry.phi) -
                                            first_odo);
            s.odometry = {p.x(), p.y(), p.phi()};
          }
          MclFilter f(map, o, rack::bench::mcl_compute_worker());
          f.init_pose({2.0, 8.0, 0.0}, 0.1, 0.05);
          for (const auto& s : before)
            (void)f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
          at.push_back(travel_to_converge(f, after, 0, 0.3));
        }
      }
      std::vector<double> sorted = at;
      std::sort(sorted.begin(), sorted.end());
      int w5 = 0, w15 = 0, w40 = 0, never = 0;
      for (double a : at) {
        w5 += a <= 5 ? 1 : 0;
        w15 += a <= 15 ? 1 : 0;
        w40 += a <= 40 ? 1 : 0;
        never += a > 1e8 ? 1 : 0;
      }
      const double med = sorted[sorted.size() / 2];
      char medtxt[32];
      if (med > 1e8) std::snprintf(medtxt, sizeof medtxt, "never");
      else std::snprintf(medtxt, sizeof medtxt, "%.1f", med);
      std::printf("| %s | %s | %d/%d | %d/%d | %d/%d | %d | %s |\n", kind == 0 ? "global" : "kidnap",
                  inj ? "**rack (injection)**" : "no injection (no recovery)", w5, seeds, w15, seeds, w40, seeds, never,
                  medtxt);
      std::fflush(stdout);
    }
  }
}

// ---- 4. a 1 kHz control task with and without MCL beside it ----------------------
struct LatencyResult {
  std::vector<uint64_t> hist;
  double max_ns = 0;
  uint64_t overruns = 0;
};

LatencyResult run_control(int seconds, const std::function<void(std::atomic<bool>&)>& load) {
  rack::ComponentRegistry registry;
  rack::components::register_builtin(registry);
  const auto caps = rack::rt::probe_capabilities();
  const int cpu = caps.online_cpus.empty() ? 0 : caps.online_cpus.back();
  const std::string text =
      "host: bench-mcl\nsystem: 0\nlcm: false\ncomponents:\n  - name: control\n    class: Generator\n"
      "    autostart: true\n    command_task: {priority: 30, cpu: " +
      std::to_string(cpu) + "}\n    data_task: {priority: 80, cpu: " + std::to_string(cpu) + ", period_ms: 1}\n";
  auto loaded = rack::load_host_text(text, "bench_mcl.yaml", registry, caps);
  if (!loaded.errors.empty()) throw std::runtime_error(loaded.errors.front().str());
  rack::ExecutorOptions eo;
  eo.allow_rt_fallback = false;
  eo.log = [](const std::string&) {};
  rack::Executor executor(std::move(loaded.host), eo);
  executor.start();
  std::atomic<bool> stop{false};
  std::thread worker([&] { load(stop); });
  rack::rt::sleep_for(static_cast<int64_t>(seconds) * rack::rt::kNsPerSec);
  auto* gen = dynamic_cast<rack::DataComponentBase*>(executor.find("control"));
  LatencyResult r;
  auto hist = std::make_unique<std::array<uint64_t, rack::rt::LatencyStats::kBuckets>>();
  gen->data_task_stats().copy_histogram(*hist);
  const auto s = gen->data_task_stats().summary();
  stop = true;
  worker.join();
  executor.stop();
  r.hist.assign(hist->begin(), hist->end());
  r.max_ns = static_cast<double>(s.max_ns);
  r.overruns = s.overruns;
  return r;
}

void bench_latency(const rack::maps::OccupancyMap& map, const std::vector<Step>& steps, int seconds) {
  const auto caps = rack::rt::probe_capabilities();
  std::printf("\n### 1 kHz control task with and without MCL running\n\n");
  if (!caps.sched_fifo) {
    std::printf("Skipped: no SCHED_FIFO rights (run as root).\n");
    return;
  }
  const int cpu = caps.online_cpus.empty() ? 0 : caps.online_cpus.back();
  std::printf(
      "A Generator data task at SCHED_FIFO 80, 1 ms period, pinned to CPU %d, in an executor with the "
      "memory policy applied (mlockall); %d s idle, then %d s with MCL updating continuously (every scan, "
      "2000 particles, 60 beams) in a SCHED_OTHER thread of the same process, unpinned (as MCL's priority-0 "
      "data task runs in rackd). Wake-up latency histogram of the control task, 1-us buckets.\n\n",
      cpu, seconds, seconds);
  const auto mem = rack::rt::apply_memory_policy(64u << 20);
  (void)mem;
  rack::bench::PmQosHold qos(0);
  std::atomic<uint64_t> mcl_updates{0};
  const auto idle = run_control(seconds, [](std::atomic<bool>& stop) {
    while (!stop) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  });
  const auto busy = run_control(seconds, [&](std::atomic<bool>& stop) {
    (void)rack::rt::set_current_thread_priority(0);
    MclOptions o;
    o.particles_min = 2000;
    o.particles_max = 2000;
    o.update_distance = 0;
    o.update_angle = 0;
    o.seed = 3;
    while (!stop) {
      MclFilter f(map, o,
                  rack::bench::mcl_compute_worker());  // re-created each pass: allocation churn, as after an INIT
      f.init_pose({steps[0].truth.x, steps[0].truth.y, steps[0].truth.phi}, 0.1, 0.05);
      for (std::size_t i = 0; i < steps.size() && !stop; ++i) {
        const auto& s = steps[i];
        (void)f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
        mcl_updates.fetch_add(1);
      }
    }
  });
  const Percentiles a = rack::bench::percentiles_of_histogram(idle.hist, idle.max_ns);
  const Percentiles b = rack::bench::percentiles_of_histogram(busy.hist, busy.max_ns);
  std::printf(
      "| side | samples | p50 us | p90 us | p99 us | p99.9 us | max us | missed periods |\n|---|---|---|---|---|---|---|---|\n");
  std::printf("| control task, idle (reference) | %lu | %.0f | %.0f | %.0f | %.0f | %.0f | %lu |\n",
              static_cast<unsigned long>(a.samples), a.p50_ns / 1e3, a.p90_ns / 1e3, a.p99_ns / 1e3, a.p999_ns / 1e3,
              a.max_ns / 1e3, static_cast<unsigned long>(idle.overruns));
  std::printf("| **control task, MCL running** | %lu | %.0f | %.0f | %.0f | %.0f | %.0f | %lu |\n",
              static_cast<unsigned long>(b.samples), b.p50_ns / 1e3, b.p90_ns / 1e3, b.p99_ns / 1e3, b.p999_ns / 1e3,
              b.max_ns / 1e3, static_cast<unsigned long>(busy.overruns));
  std::printf("\nRatio with MCL / idle: p99 **%.2fx** (target <= 1.2x), p50 %.2fx; MCL updates during the run: %lu.\n",
              a.p99_ns > 0 ? b.p99_ns / a.p99_ns : 0.0, a.p50_ns > 0 ? b.p50_ns / a.p50_ns : 0.0,
              static_cast<unsigned long>(mcl_updates.load()));
}

// Writes the tour as a CARMEN log: ODOM at every step (0.1 s), ROBOTLASER1 at every
// second step with `beams` beams, TRUEPOS (ground truth, which replay ignores). The
// laser sits at the robot's reference point.
int write_carmen(const rack::maps::OccupancyMap& map, const std::string& path, std::size_t max_steps, int beams) {
  SimConfig cfg;
  cfg.beams = beams;
  ScriptedRobot robot(map, cfg, 1);
  robot.place({kTour[0].first, kTour[0].second, 0.0});
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    std::fprintf(stderr, "bench_mcl: cannot write %s\n", path.c_str());
    return 1;
  }
  std::fprintf(
      f,
      "# CARMEN Logfile\n# written by bench_mcl --write-carmen: the scripted robot's tour of "
      "configs/maps/office.yaml (1 cm range noise, 2 %% odometry noise); TRUEPOS is the ground truth\n"
      "# message formats: ODOM, ROBOTLASER1, TRUEPOS (see components/replay/include/rack/replay/carmen_log.h)\n");
  std::size_t step = 0;
  for (std::size_t w = 1; w < kTour.size() && step < max_steps; ++w) {
    for (int guard = 0; guard < 5000 && step < max_steps && !robot.step_towards(kTour[w].first, kTour[w].second);
         ++guard, ++step) {
      const double t = 1000.0 + 0.1 * static_cast<double>(step);
      const SimPose o = robot.odometry(), tr = robot.truth();
      std::fprintf(f, "ODOM %.4f %.4f %.5f 0.5 0 0 %.3f sim %.3f\n", o.x, o.y, o.phi, t, t);
      std::fprintf(f, "TRUEPOS %.4f %.4f %.5f %.4f %.4f %.5f %.3f sim %.3f\n", tr.x, tr.y, tr.phi, o.x, o.y, o.phi, t,
                   t);
      if (step % 2 != 0) continue;
      const SimScan s = robot.scan();
      std::fprintf(f, "ROBOTLASER1 0 %.5f %.5f %.6f %.1f 0.01 0 %zu", double{s.start_angle}, 1.5 * std::numbers::pi,
                   double{s.step}, double{s.max_range}, s.ranges.size());
      for (float r : s.ranges) std::fprintf(f, " %.3f", double{r});
      std::fprintf(f, " 0 %.4f %.4f %.5f %.4f %.4f %.5f 0.5 0 0 0 0 %.3f sim %.3f\n", o.x, o.y, o.phi, o.x, o.y, o.phi,
                   t, t);
    }
  }
  std::fclose(f);
  std::printf("bench_mcl: wrote %zu steps to %s\n", step, path.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, latency = true, update = true, accuracy = true, recovery = true;
  int latency_seconds = 20;
  std::vector<uint32_t> particles;
  std::size_t scans = 0;
  std::string json;
  std::string carmen;
  std::size_t carmen_steps = 400;
  int carmen_beams = 91;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--no-latency") latency = false;
    else if (a == "--latency-seconds" && i + 1 < argc) latency_seconds = std::atoi(argv[++i]);
    else if (a == "--write-carmen" && i + 1 < argc) carmen = argv[++i];
    else if (a == "--steps" && i + 1 < argc) carmen_steps = static_cast<std::size_t>(std::atol(argv[++i]));
    else if (a == "--beams" && i + 1 < argc) carmen_beams = std::atoi(argv[++i]);
    else if (a == "--scans" && i + 1 < argc) scans = static_cast<std::size_t>(std::atol(argv[++i]));
    else if (a == "--json" && i + 1 < argc) json = argv[++i];
    else if (a == "--threads" && i + 1 < argc)
      g_threads = static_cast<uint32_t>(std::clamp(std::atoi(argv[++i]), 1, 2));
    else if (a == "--particles" && i + 1 < argc) {
      for (const char* p = argv[++i]; *p != '\0';) {
        char* end = nullptr;
        const unsigned long v = std::strtoul(p, &end, 10);
        if (end == p || v == 0) {
          std::fprintf(stderr, "bench_mcl: --particles: expected N,N,... (positive counts)\n");
          return 2;
        }
        particles.push_back(static_cast<uint32_t>(v));
        p = *end == ',' ? end + 1 : end;
      }
    } else if (a == "--parts" && i + 1 < argc) {
      const std::string parts = std::string(",") + argv[++i] + ",";
      const auto has = [&](const char* name) { return parts.find(std::string(",") + name + ",") != std::string::npos; };
      update = has("update");
      accuracy = has("accuracy");
      recovery = has("recovery");
      latency = has("latency");
      if (!update && !accuracy && !recovery && !latency) {
        std::fprintf(stderr, "bench_mcl: --parts: any of update,accuracy,recovery,latency\n");
        return 2;
      }
    } else if (a == "-h" || a == "--help") {
      std::printf(
          "bench_mcl [--quick] [--no-latency] [--latency-seconds S] [--parts update,accuracy,recovery,latency]\n"
          "          [--particles N,N,...] [--scans N] [--threads 1|2] [--json FILE]\n"
          "bench_mcl --write-carmen FILE [--steps N] [--beams B]   write the simulated tour as a CARMEN log\n");
      return 0;
    } else {
      std::fprintf(stderr, "bench_mcl: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  const std::string map_path = std::string(RACK_SOURCE_DIR) + "/configs/maps/office.yaml";
  auto loaded = rack::maps::load_map(map_path);
  if (!loaded.ok()) {
    std::fprintf(stderr, "bench_mcl: %s\n", loaded.error_text().c_str());
    return 1;
  }
  const rack::maps::OccupancyMap& map = *loaded.map;
  if (!carmen.empty()) return write_carmen(map, carmen, carmen_steps, carmen_beams);
  std::printf("bench_mcl: kernel %s (%s), %s, %ld CPUs; loadavg %s\n", rack::bench::kernel_string().c_str(),
              rack::bench::kernel_is_preempt_rt() ? "PREEMPT_RT" : "not PREEMPT_RT", rack::bench::cpu_model().c_str(),
              sysconf(_SC_NPROCESSORS_ONLN), rack::bench::read_first_line("/proc/loadavg").c_str());
  const auto steps = record(map, 1);
  std::printf("bench_mcl: map %s, tour of %zu scans\n", map_path.c_str(), steps.size());
  std::vector<UpdateResult> updates;
  if (update) updates = bench_update_time(map, steps, quick, particles, scans);
  if (accuracy) bench_accuracy(map, quick);
  if (recovery) bench_recovery(map, quick);
  if (latency) bench_latency(map, steps, quick ? 5 : latency_seconds);
  if (!json.empty()) {
    std::string j = "{\"machine\": " + rack::bench::json_machine() + ", \"scans_per_round\": " +
                    std::to_string(std::min<std::size_t>(steps.size(), scans > 0 ? scans : (quick ? 150 : 400))) +
                    ", \"rounds\": 2, \"target_ratio\": 1.1, \"update\": [";
    for (std::size_t i = 0; i < updates.size(); ++i) {
      const auto& u = updates[i];
      j += std::string(i ? ", " : "") + "{\"particles\": " + std::to_string(u.particles) +
           ", \"points\": " + std::to_string(u.points) + ", \"mrpt_decimation\": " + std::to_string(u.decimation) +
           ", \"rack\": " + rack::bench::json_percentiles(u.rack) +
           ", \"mrpt\": " + rack::bench::json_percentiles(u.mrpt) +
           ", \"median_pair_ratio\": " + rack::bench::json_number(u.median_pair_ratio) + "}";
    }
    j += "]}\n";
    if (!rack::bench::write_file(json, j)) {
      std::fprintf(stderr, "bench_mcl: cannot write %s\n", json.c_str());
      return 1;
    }
  }
  std::printf("\nbench_mcl: loadavg after: %s\n", rack::bench::read_first_line("/proc/loadavg").c_str());
  return 0;
}
