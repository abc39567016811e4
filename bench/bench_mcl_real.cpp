// bench_mcl_real: localisation accuracy on real recorded data (issue 18). RACK-RT's MCL
// filter (rack::mcl::MclFilter, driven directly, no rackd) beside MRPT's filter alone
// (mcl_reference.h: CMonteCarloLocalization2D with the same map, scans, particle count
// and option values) on the same data in the same run, several seeds.
//
// Datasets: bench/data/carmen/NAME.log.gz + NAME.yaml (real CARMEN logs of four
// buildings, GMapping-corrected poses as the reference, synthetic odometry; see the
// README there) and the simulated tour of the office map (mcl_sim.h, configs/maps/).
//
// Per dataset and side: ATE RMSE (position error at every scan, RMS), lost poses (error
// above 0.5 m), rotation RMSE, relative error between consecutive scans (mean of the
// translation and rotation error of the estimated motion against the reference's),
// recovery injections, updates where the odometry check disagreed (rack), update time
// (p50/p95, wall and CPU time). Then kidnapping on the real data: the robot is carried from a third of the
// log to two thirds (or the points --kidnap gives) while its odometry goes on as if it had
// driven one normal step; how far it travels until the estimate is within 0.5 m again and
// stays (rack with its recovery; MRPT alone has none).
//
//   bench_mcl_real [--quick] [--seeds N] [--particles N] [--datasets a,b,...]
//                  [--parts track,kidnap,global] [--global-seeds N] [--global-particles N]
//                  [--global-scans N] [--json FILE] [--markdown FILE] [--perfect-odometry]
//                  [--kidnap FROM:TO[,FROM:TO...]]
//   (default parts: track,kidnap; global: 10 seeds, 300..20000 particles, first 200 scans;
//   kidnap 1/3:2/3, fractions of each log as a/b or decimals)
//
// Experiment knobs (environment, for choosing defaults; not used by bench/run):
// MCL_TRACE=1 prints every scan of rack's filter to stderr (error, fit, consistency,
// recovery state); MCL_INJECT, MCL_RATIO, MCL_LOW, MCL_OUTLIER, MCL_OSCALE, MCL_A1,
// MCL_A3, MCL_SIGMA, MCL_BEAMS, MCL_KLD_XY, MCL_KLD_PHI, MCL_KLD_EPS override the
// option of that name on both sides; MCL_PMIN sets particles_min (KLD while tracking,
// both sides); MCL_TRACE also traces the global part. MCL_CHECK, MCL_CHECK_FRAC,
// MCL_CHECK_GOOD set odometry_check, odometry_check_fraction, odometry_check_goodness
// (rack only: MRPT alone has no such check). MCL_RACK_ONLY=1 leaves MRPT alone out of the
// tracking, kidnap and global parts (quicker experiments on rack's side; no target lines).
// In the kidnap part MCL_TRACE prints every scan from the kidnap on: the fit at the true
// pose beside the cloud's, and the particles (and this update's injected ones) near it.
//
// Not RT code; needs no privileges.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <map>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "mcl_dataset.h"
#include "mcl_reference.h"
#include "mcl_worker.h"
#include "mcl_sim.h"
#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"

namespace {

using rack::bench::MrptReference;
using rack::mcl::MclFilter;
using rack::mcl::MclOptions;
using rack::test::DatasetStep;
using rack::test::SimPose;

constexpr double kLost = 0.5;  // m
constexpr double kDeg = 180.0 / std::numbers::pi;

std::string g_md;  // the report (markdown), also printed
void out(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
void out(const char* fmt, ...) {
  char buf[4096];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  g_md += buf;
  std::fputs(buf, stdout);
  std::fflush(stdout);
}

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
// CPU time of the process (all its threads: the filter's helper thread too), ms. An
// update's wall time on a loaded machine includes the time slices other processes
// ran in; its CPU time does not, so the p95 of the CPU time is the filter's own tail.
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

struct Data {
  std::string name, about;
  std::optional<rack::maps::OccupancyMap> map;
  std::vector<DatasetStep> steps;
  bool real = true;
};

// The simulated tour (as bench_mcl's accuracy part), as dataset steps.
const std::vector<std::pair<double, double>> kTour = {{2.0, 8.0},   {9.6, 8.0},  {9.6, 4.0},  {11.0, 3.0},
                                                      {9.6, 4.0},   {9.6, 8.0},  {18.0, 8.0}, {19.6, 11.5},
                                                      {19.6, 13.5}, {19.6, 8.0}, {4.0, 8.0}};
std::vector<DatasetStep> sim_tour(const rack::maps::OccupancyMap& map, uint64_t seed) {
  rack::test::ScriptedRobot robot(map, rack::test::SimConfig{}, seed);
  robot.place({kTour[0].first, kTour[0].second, 0.0});
  std::vector<DatasetStep> steps;
  for (std::size_t w = 1; w < kTour.size(); ++w) {
    for (int guard = 0; guard < 5000 && !robot.step_towards(kTour[w].first, kTour[w].second); ++guard) {
      DatasetStep s;
      s.odometry = robot.odometry();
      s.truth = robot.truth();
      s.scan = robot.scan();
      s.time = 0.1 * static_cast<double>(steps.size());
      steps.push_back(std::move(s));
    }
  }
  return steps;
}

struct Score {
  std::size_t n = 0, lost = 0, rel_n = 0;
  double se = 0, sr = 0, rel_t = 0, rel_r = 0, max_err = 0;
  std::vector<double> times;  // ms per update call (wall)
  std::vector<double> cpu;    // ms of CPU time per update call
  uint64_t injections = 0;    // updates that injected
  uint64_t scan_incr = 0;     // updates where the odometry check moved part of the particles by the scans' increment
  void add(const SimPose& e, const SimPose& t) {
    const double d = std::hypot(e.x - t.x, e.y - t.y);
    se += d * d;
    sr += std::pow(rack::test::angle_diff(e.phi, t.phi), 2);
    lost += d > kLost ? 1 : 0;
    max_err = std::max(max_err, d);
    ++n;
  }
  void add_rel(const SimPose& e0, const SimPose& e1, const SimPose& t0, const SimPose& t1) {
    const mrpt::poses::CPose2D de = mrpt::poses::CPose2D(e1.x, e1.y, e1.phi) - mrpt::poses::CPose2D(e0.x, e0.y, e0.phi);
    const mrpt::poses::CPose2D dt = mrpt::poses::CPose2D(t1.x, t1.y, t1.phi) - mrpt::poses::CPose2D(t0.x, t0.y, t0.phi);
    rel_t += std::hypot(de.x() - dt.x(), de.y() - dt.y());
    rel_r += std::fabs(rack::test::angle_diff(de.phi(), dt.phi()));
    ++rel_n;
  }
  [[nodiscard]] double ate() const { return std::sqrt(se / static_cast<double>(std::max<std::size_t>(n, 1))); }
  [[nodiscard]] double rot() const { return std::sqrt(sr / static_cast<double>(std::max<std::size_t>(n, 1))) * kDeg; }
  [[nodiscard]] static double pct(std::vector<double> v, double q) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  }
};

uint32_t decimation_for(const DatasetStep& s, uint32_t beams) {
  return beams == 0 ? 1 : std::max<uint32_t>(1, static_cast<uint32_t>(s.scan.ranges.size() / beams));
}

// MCL_RACK_ONLY=1: the tracking and global parts run rack's filter alone (no MRPT side,
// no targets; MRPT's column then reads "never").
bool rack_only() { return std::getenv("MCL_RACK_ONLY") != nullptr; }

MclOptions bench_options(uint32_t particles, uint64_t seed) {
  MclOptions o;  // the defaults, with a fixed particle count for the side-by-side
  o.particles_min = particles;
  o.particles_max = particles;
  o.seed = seed;
  if (const char* v = std::getenv("MCL_INJECT")) o.inject_max_fraction = std::atof(v);  // experiments
  if (const char* v = std::getenv("MCL_RATIO")) o.recovery_ratio = std::atof(v);
  if (const char* v = std::getenv("MCL_LOW")) o.recovery_updates = static_cast<uint32_t>(std::atoi(v));
  if (const char* v = std::getenv("MCL_OUTLIER")) o.odom_outlier_fraction = std::atof(v);
  if (const char* v = std::getenv("MCL_OSCALE")) o.odom_outlier_scale = std::atof(v);
  if (const char* v = std::getenv("MCL_A1")) o.odom_a1 = std::atof(v);
  if (const char* v = std::getenv("MCL_A3")) o.odom_a3 = std::atof(v);
  if (const char* v = std::getenv("MCL_SIGMA")) o.sigma_hit = std::atof(v);
  if (const char* v = std::getenv("MCL_BEAMS")) o.beams = static_cast<uint32_t>(std::atoi(v));
  if (const char* v = std::getenv("MCL_KLD_XY")) o.kld_bin_xy = std::atof(v);
  if (const char* v = std::getenv("MCL_KLD_PHI")) o.kld_bin_phi = std::atof(v);
  if (const char* v = std::getenv("MCL_KLD_EPS")) o.kld_epsilon = std::atof(v);
  if (const char* v = std::getenv("MCL_CHECK")) o.odometry_check = std::atof(v);
  if (const char* v = std::getenv("MCL_CHECK_FRAC")) o.odometry_check_fraction = std::atof(v);
  if (const char* v = std::getenv("MCL_CHECK_GOOD")) o.odometry_check_goodness = std::atof(v);
  if (const char* v = std::getenv("MCL_GLOBAL_K")) o.global_candidates = static_cast<uint32_t>(std::atoi(v));
  if (const char* v = std::getenv("MCL_PMIN"))
    o.particles_min = static_cast<uint32_t>(std::atoi(v));  // KLD in tracking
  return o;
}

// Runs rack's filter over the steps (init around the first reference pose).
Score run_rack(const Data& d, const std::vector<DatasetStep>& steps, const MclOptions& o) {
  Score sc;
  MclFilter f(*d.map, o, rack::bench::mcl_compute_worker());
  const SimPose& t0 = steps[0].truth;
  f.init_pose({t0.x, t0.y, t0.phi}, 0.2, 0.1);
  SimPose prev_e{}, prev_t{};
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const auto& s = steps[i];
    const double a = now_ms(), ca = cpu_ms();
    const bool ran = f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
    const double cb = cpu_ms(), b = now_ms();
    if (ran) {
      sc.times.push_back(b - a);
      sc.cpu.push_back(cb - ca);
    }
    const auto e = f.estimate();
    if (ran && e.injected > 0) ++sc.injections;
    if (ran && e.odometry_disagreed) ++sc.scan_incr;
    const SimPose ep{e.pose.x, e.pose.y, e.pose.phi};
    if (std::getenv("MCL_TRACE") != nullptr) {
      std::fprintf(stderr,
                   "%zu err %.3f dphi %.3f fit %.3f cons %.3f ratio %.3f low %u inj %u n %u sd %.3f m %.3f rad%s "
                   "odo_step %.2f ms %.3f\n",
                   i, std::hypot(ep.x - s.truth.x, ep.y - s.truth.y), rack::test::angle_diff(ep.phi, s.truth.phi),
                   e.fit, e.consistency, e.w_fast / e.w_slow, e.low_updates, e.injected, e.particles,
                   std::sqrt(e.covariance[0] + e.covariance[4]), std::sqrt(e.covariance[8]),
                   ran && e.odometry_disagreed ? " scan-incr" : "",
                   i > 0 ? std::hypot(s.odometry.x - steps[i - 1].odometry.x, s.odometry.y - steps[i - 1].odometry.y)
                         : 0.0,
                   ran ? sc.cpu.back() : 0.0);
    }
    sc.add(ep, s.truth);
    if (i > 0) sc.add_rel(prev_e, ep, prev_t, s.truth);
    prev_e = ep;
    prev_t = s.truth;
  }
  return sc;
}

Score run_mrpt(const Data& d, const std::vector<DatasetStep>& steps, const MclOptions& o) {
  Score sc;
  mrpt::random::getRandomGenerator().randomize(static_cast<uint32_t>(o.seed));
  MrptReference ref(*d.map, o);
  ref.set_decimation(decimation_for(steps[0], o.beams));
  ref.init_pose(steps[0].truth, 0.2, 0.1, o.seed);
  SimPose prev_e{}, prev_t{};
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const auto& s = steps[i];
    const double a = now_ms(), ca = cpu_ms();
    const bool ran = ref.update(s.odometry, s.scan, true);
    const double cb = cpu_ms(), b = now_ms();
    if (ran) {
      sc.times.push_back(b - a);
      sc.cpu.push_back(cb - ca);
    }
    const SimPose ep = ref.estimate();
    sc.add(ep, s.truth);
    if (i > 0) sc.add_rel(prev_e, ep, prev_t, s.truth);
    prev_e = ep;
    prev_t = s.truth;
  }
  return sc;
}

struct Agg {
  std::vector<Score> runs;
};

std::string range_text(const std::vector<double>& v, int decimals) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  char a[32], b[32];
  std::snprintf(a, sizeof a, "%.*f", decimals, *lo);
  std::snprintf(b, sizeof b, "%.*f", decimals, *hi);
  return std::string(a) == b ? std::string(a) : std::string(a) + "-" + b;
}

struct Row {
  std::string dataset, side;
  double ate_max = 0, rot_max = 0;
  double p95_max = 0, cpu95_max = 0;  // update time, worst seed (wall, CPU)
  std::size_t lost_total = 0;
};
std::vector<Row> g_rows;

void print_side(const std::string& dataset, const char* side, const std::vector<Score>& runs) {
  std::vector<double> ate, rot, lost, rt, rr, inj, chk, p50, p95, c50, c95;
  std::size_t lost_total = 0;
  for (const auto& s : runs) {
    ate.push_back(s.ate());
    rot.push_back(s.rot());
    lost.push_back(static_cast<double>(s.lost));
    lost_total += s.lost;
    rt.push_back(s.rel_t / static_cast<double>(std::max<std::size_t>(s.rel_n, 1)));
    rr.push_back(s.rel_r / static_cast<double>(std::max<std::size_t>(s.rel_n, 1)) * kDeg);
    inj.push_back(static_cast<double>(s.injections));
    chk.push_back(static_cast<double>(s.scan_incr));
    p50.push_back(Score::pct(s.times, 0.5));
    p95.push_back(Score::pct(s.times, 0.95));
    c50.push_back(Score::pct(s.cpu, 0.5));
    c95.push_back(Score::pct(s.cpu, 0.95));
  }
  const bool rack = std::string(side).find("RACK") != std::string::npos;
  out("| %s | %s | %s | %s of %zu | %s | %s m, %s deg | %s | %s | %s / %s | %s / %s |\n", dataset.c_str(), side,
      range_text(ate, 3).c_str(), range_text(lost, 0).c_str(), runs[0].n, range_text(rot, 2).c_str(),
      range_text(rt, 3).c_str(), range_text(rr, 2).c_str(), range_text(inj, 0).c_str(),
      rack ? range_text(chk, 0).c_str() : "-", range_text(p50, 2).c_str(), range_text(p95, 2).c_str(),
      range_text(c50, 2).c_str(), range_text(c95, 2).c_str());
  const auto max_of = [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); };
  g_rows.push_back({dataset, side, max_of(ate), max_of(rot), max_of(p95), max_of(c95), lost_total});
}

void part_track(const std::vector<Data>& sets, int seeds, uint32_t particles) {
  out("\n### Tracking: RACK-RT MCL (default options) beside MRPT alone, %u particles, seeds 1..%d\n\n", particles,
      seeds);
  out("Both filters start from the first reference pose with a spread of 0.2 m / 0.1 rad and get every scan "
      "(gating: 0.10 m or 0.10 rad of odometry); rack's filter takes %u of the echoes as points, MRPT its own "
      "CObservation2DRangeScan with LF_decimation n/%u. Same option values on both sides (MclOptions defaults "
      "given to MRPT's option structs), fixed particle count. Errors at every scan against the reference; "
      "figures are the range over the seeds.\n\n",
      MclOptions{}.beams, MclOptions{}.beams);
  out("| dataset | side | ATE RMSE m | lost (> 0.5 m) | rotation RMSE deg | relative error (consecutive scans) | "
      "injections | odometry check disagreed | update p50 / p95 ms | update CPU time p50 / p95 ms |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& d : sets) {
    std::vector<Score> r, m;
    for (int seed = 1; seed <= seeds; ++seed) {
      std::vector<DatasetStep> steps = d.real ? d.steps : sim_tour(*d.map, static_cast<uint64_t>(seed));
      const MclOptions o = bench_options(particles, static_cast<uint64_t>(seed));
      r.push_back(run_rack(d, steps, o));
      if (!rack_only()) m.push_back(run_mrpt(d, steps, o));
    }
    print_side(d.name, "**RACK-RT MCL**", r);
    if (!rack_only()) print_side(d.name, "MRPT alone", m);
  }
  if (rack_only()) return;
  out("\nTargets (default options, real data): 0 lost poses; ATE and rotation RMSE within 1.1x MRPT alone; "
      "update p95 at most 0.6x MRPT alone's (worst seed against worst seed; lost poses summed over the seeds; "
      "the update p95 in wall time, which on a loaded machine measures the scheduler, and in CPU time, the "
      "filter's own):\n\n");
  for (std::size_t i = 0; i + 1 < g_rows.size(); i += 2) {
    const Row& a = g_rows[i];
    const Row& b = g_rows[i + 1];
    out("- %s: lost %zu (%s); ATE %.3f / %.3f m = %.2fx (%s); rotation %.2f / %.2f deg = %.2fx (%s); "
        "update p95 %.2f / %.2f ms = %.2fx (%s), CPU time %.2f / %.2f ms = %.2fx (%s)\n",
        a.dataset.c_str(), a.lost_total, a.lost_total == 0 ? "met" : "MISSED", a.ate_max, b.ate_max,
        a.ate_max / b.ate_max, a.ate_max <= 1.1 * b.ate_max ? "met" : "MISSED", a.rot_max, b.rot_max,
        a.rot_max / b.rot_max, a.rot_max <= 1.1 * b.rot_max ? "met" : "MISSED", a.p95_max, b.p95_max,
        a.p95_max / b.p95_max, a.p95_max <= 0.6 * b.p95_max ? "met" : "MISSED", a.cpu95_max, b.cpu95_max,
        a.cpu95_max / b.cpu95_max, a.cpu95_max <= 0.6 * b.cpu95_max ? "met" : "MISSED");
  }
}

// The robot is carried: scans from `from` jump to `to`; the odometry goes on from where
// it was with the increment of one normal step (the one before `to`).
std::vector<DatasetStep> kidnapped(const std::vector<DatasetStep>& steps, std::size_t from, std::size_t to) {
  std::vector<DatasetStep> out_steps(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(from));
  const auto pose = [](const SimPose& p) { return mrpt::poses::CPose2D(p.x, p.y, p.phi); };
  const mrpt::poses::CPose2D base = pose(steps[from - 1].odometry) +
                                    (pose(steps[to].odometry) - pose(steps[to - 1].odometry));
  const mrpt::poses::CPose2D first = pose(steps[to].odometry);
  for (std::size_t i = to; i < steps.size(); ++i) {
    DatasetStep s = steps[i];
    const mrpt::poses::CPose2D o = base + (pose(s.odometry) - first);
    s.odometry = {o.x(), o.y(), o.phi()};
    out_steps.push_back(std::move(s));
  }
  return out_steps;
}

// Travel (reference) after `from` until the estimate is within kLost and stays so to
// the end; negative when never.
template <typename Estimate>
double recovered_after(const std::vector<DatasetStep>& steps, std::size_t from, const std::vector<SimPose>& est) {
  double travelled = 0, at = -1;
  for (std::size_t i = from; i < steps.size(); ++i) {
    if (i > from)
      travelled += std::hypot(steps[i].truth.x - steps[i - 1].truth.x, steps[i].truth.y - steps[i - 1].truth.y);
    const bool good = std::hypot(est[i].x - steps[i].truth.x, est[i].y - steps[i].truth.y) < kLost;
    if (!good) at = -1;
    else if (at < 0) at = travelled;
  }
  return at;
}

// A kidnap point: the robot is carried from `from` to `to` (fractions of the log).
struct KidnapPoint {
  double from = 1.0 / 3.0, to = 2.0 / 3.0;
  std::string text = "1/3:2/3";
};

// "a/b" or a decimal fraction in (0, 1); negative when malformed.
double parse_fraction(const std::string& t) {
  char* end = nullptr;
  const double a = std::strtod(t.c_str(), &end);
  if (end == t.c_str()) return -1.0;
  if (*end == '\0') return a > 0.0 && a < 1.0 ? a : -1.0;
  if (*end != '/') return -1.0;
  const char* b_text = end + 1;
  const double b = std::strtod(b_text, &end);
  if (end == b_text || *end != '\0' || !(b > 0.0)) return -1.0;
  const double f = a / b;
  return f > 0.0 && f < 1.0 ? f : -1.0;
}

// "1/3:2/3,1/2:5/6": kidnap points, FROM before TO; empty when malformed.
std::vector<KidnapPoint> parse_kidnap_points(const std::string& text) {
  std::vector<KidnapPoint> points;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t comma = std::min(text.find(',', at), text.size());
    const std::string item = text.substr(at, comma - at);
    const std::size_t colon = item.find(':');
    if (colon == std::string::npos) return {};
    KidnapPoint k;
    k.from = parse_fraction(item.substr(0, colon));
    k.to = parse_fraction(item.substr(colon + 1));
    k.text = item;
    if (k.from < 0.0 || k.to < 0.0 || !(k.from < k.to)) return {};
    points.push_back(k);
    at = comma + 1;
  }
  return points;
}

// The scan fit (MclEstimate::fit) of one given pose: a one-particle filter put there
// without motion noise, for MCL_TRACE's "fit at the true pose".
class FitProbe {
 public:
  FitProbe(const rack::maps::OccupancyMap& map, MclOptions o) : f_(map, probe_options(o)) {}
  double fit_at(const SimPose& p, const DatasetStep& s) {
    f_.init_pose({p.x, p.y, p.phi}, 0.0, 0.0);
    (void)f_.update({0.0, 0.0, 0.0}, s.scan.xs, s.scan.ys);
    return f_.estimate().fit;
  }

 private:
  static MclOptions probe_options(MclOptions o) {
    o.particles_min = o.particles_max = 1;
    o.odom_min_std_xy = o.odom_min_std_phi = 1e-9;
    o.odom_outlier_fraction = 0.0;
    o.odometry_check = 0.0;
    o.inject_max_fraction = 0.0;
    o.global_candidates = 1;
    o.threads = 1;
    return o;
  }
  MclFilter f_;
};

// MCL_TRACE: one line per scan after the kidnap: the error, the cloud's mean fit beside
// the fit at the true pose, the recovery state, and how the particles stand near the
// true pose (within 0.5 m and 0.3 rad): their weight share, and how many of this
// update's injected ones (the last `injected` of the set) landed there.
void trace_kidnap(MclFilter& f, FitProbe& probe, const DatasetStep& s, std::size_t i) {
  const auto e = f.estimate();
  std::vector<float> x(e.particles), y(e.particles), phi(e.particles), w(e.particles);
  const std::size_t n = f.sample_particles(x, y, phi, w);
  double near_w = 0.0;
  std::size_t inj_near = 0;
  double inj_best = 1e9;
  for (std::size_t k = 0; k < n; ++k) {
    const double d = std::hypot(x[k] - s.truth.x, y[k] - s.truth.y);
    const double a = std::fabs(rack::test::angle_diff(phi[k], s.truth.phi));
    const bool near = d < kLost && a < 0.3;
    near_w += near ? w[k] : 0.0;
    if (n == e.particles && k + e.injected >= n) {
      inj_near += near ? 1 : 0;
      inj_best = std::min(inj_best, d + a);  // m + rad: a rough pose distance
    }
  }
  std::fprintf(stderr,
               "kidnap %zu err %.2f fit %.3f fit_truth %.3f cons %.2f ratio %.2f low %u inj %u n %u sd %.2f "
               "near_w %.3f inj_near %zu inj_best %.2f\n",
               i, std::hypot(e.pose.x - s.truth.x, e.pose.y - s.truth.y), e.fit, probe.fit_at(s.truth, s),
               e.consistency, e.w_fast / e.w_slow, e.low_updates, e.injected, e.particles,
               std::sqrt(e.covariance[0] + e.covariance[4]), near_w, inj_near, e.injected > 0 ? inj_best : 0.0);
}

void part_kidnap(const std::vector<Data>& sets, int seeds, uint32_t particles, const std::vector<KidnapPoint>& points) {
  const bool mrpt = !rack_only();
  const char* trace = std::getenv("MCL_TRACE");
  for (const KidnapPoint& kp : points) {
    out("\n### Kidnapping on real data: carried from %s of the log to %s, odometry unaware\n\n",
        kp.text.substr(0, kp.text.find(':')).c_str(), kp.text.substr(kp.text.find(':') + 1).c_str());
    out("Travel (reference, m) after the kidnap until the estimate is within %.1f m and stays so to the end of the "
        "log (never: not recovered); seeds 1..%d, %u particles; lost poses before the kidnap in brackets.%s\n\n",
        kLost, seeds, particles, mrpt ? "" : " MRPT alone not run (MCL_RACK_ONLY).");
    out("| dataset | jump m | travel after it m | RACK-RT MCL | recovered | MRPT alone |\n|---|---|---|---|---|---|\n");
    for (const auto& d : sets) {
      if (!d.real) continue;
      const auto from = static_cast<std::size_t>(kp.from * static_cast<double>(d.steps.size()));
      const auto to = static_cast<std::size_t>(kp.to * static_cast<double>(d.steps.size()));
      if (from < 2 || to <= from || to + 2 >= d.steps.size()) continue;
      const auto steps = kidnapped(d.steps, from, to);
      const double jump = std::hypot(d.steps[to].truth.x - d.steps[from - 1].truth.x,
                                     d.steps[to].truth.y - d.steps[from - 1].truth.y);
      double after = 0.0;
      for (std::size_t i = from + 1; i < steps.size(); ++i)
        after += std::hypot(steps[i].truth.x - steps[i - 1].truth.x, steps[i].truth.y - steps[i - 1].truth.y);
      std::string rr, mm;
      int recovered = 0;
      for (int seed = 1; seed <= seeds; ++seed) {
        const MclOptions o = bench_options(particles, static_cast<uint64_t>(seed));
        std::vector<SimPose> er, em;
        std::size_t lost_r = 0, lost_m = 0;
        {
          MclFilter f(*d.map, o, rack::bench::mcl_compute_worker());
          std::optional<FitProbe> probe;
          if (trace != nullptr) probe.emplace(*d.map, o);
          f.init_pose({steps[0].truth.x, steps[0].truth.y, steps[0].truth.phi}, 0.2, 0.1);
          for (std::size_t i = 0; i < steps.size(); ++i) {
            (void)f.update({steps[i].odometry.x, steps[i].odometry.y, steps[i].odometry.phi}, steps[i].scan.xs,
                           steps[i].scan.ys);
            const auto e = f.estimate();
            er.push_back({e.pose.x, e.pose.y, e.pose.phi});
            if (i < from && std::hypot(e.pose.x - steps[i].truth.x, e.pose.y - steps[i].truth.y) > kLost) ++lost_r;
            if (probe && i + 1 >= from) {
              if (i + 1 == from) std::fprintf(stderr, "kidnap %s %s seed %d\n", d.name.c_str(), kp.text.c_str(), seed);
              trace_kidnap(f, *probe, steps[i], i);
            }
          }
        }
        if (mrpt) {
          mrpt::random::getRandomGenerator().randomize(static_cast<uint32_t>(seed));
          MrptReference ref(*d.map, o);
          ref.set_decimation(decimation_for(steps[0], o.beams));
          ref.init_pose(steps[0].truth, 0.2, 0.1, o.seed);
          for (std::size_t i = 0; i < steps.size(); ++i) {
            (void)ref.update(steps[i].odometry, steps[i].scan, true);
            em.push_back(ref.estimate());
            if (i < from && std::hypot(em.back().x - steps[i].truth.x, em.back().y - steps[i].truth.y) > kLost)
              ++lost_m;
          }
        }
        const double ar = recovered_after<int>(steps, from, er);
        recovered += ar >= 0 ? 1 : 0;
        char buf[96];
        std::snprintf(buf, sizeof buf, "%s%s [%zu]", seed > 1 ? ", " : "",
                      ar < 0 ? "never" : (std::to_string(static_cast<int>(std::lround(ar))) + " m").c_str(), lost_r);
        rr += buf;
        if (mrpt) {
          const double am = recovered_after<int>(steps, from, em);
          std::snprintf(buf, sizeof buf, "%s%s [%zu]", seed > 1 ? ", " : "",
                        am < 0 ? "never" : (std::to_string(static_cast<int>(std::lround(am))) + " m").c_str(), lost_m);
          mm += buf;
        }
      }
      out("| %s | %.1f | %.0f | %s | %d of %d | %s |\n", d.name.c_str(), jump, after, rr.c_str(), recovered, seeds,
          mrpt ? mm.c_str() : "-");
    }
  }
}

// Global localisation: uniform start over the free space; travel (reference) until the
// estimate is within 0.5 m and stays so to the end of the first `scans` scans, and the
// particle count (KLD) at the end. Both sides particles 300..max.
void part_global(const std::vector<Data>& sets, int seeds, uint32_t particles_max, std::size_t scans) {
  out("\n### Global localisation: uniform start, KLD 300..%u particles, first %zu scans, seeds 1..%d\n\n",
      particles_max, scans, seeds);
  out("Travel (reference, m) until the estimate is within %.1f m and stays so (never: not within the scans "
      "used); particle count at the last scan in brackets. MRPT alone starts from MRPT's own uniform "
      "initialisation over the free cells (resetUniformFreeSpace).\n\n",
      kLost);
  out("| dataset | RACK-RT MCL | MRPT alone | converged (rack / MRPT) | rack within 2x MRPT's travel |\n|---|---|---|---|---|\n");
  for (const auto& d : sets) {
    if (!d.real) continue;
    const std::vector<DatasetStep> steps(
        d.steps.begin(), d.steps.begin() + static_cast<std::ptrdiff_t>(std::min(scans, d.steps.size())));
    std::string rr, mm;
    int conv_r = 0, conv_m = 0, within = 0;
    for (int seed = 1; seed <= seeds; ++seed) {
      MclOptions o = bench_options(particles_max, static_cast<uint64_t>(seed));
      o.particles_min = 300;
      std::vector<SimPose> er, em;
      std::size_t nr = 0, nm = 0;
      {
        MclFilter f(*d.map, o, rack::bench::mcl_compute_worker());
        f.init_global();
        for (const auto& s : steps) {
          (void)f.update({s.odometry.x, s.odometry.y, s.odometry.phi}, s.scan.xs, s.scan.ys);
          const auto e = f.estimate();
          er.push_back({e.pose.x, e.pose.y, e.pose.phi});
          nr = e.particles;
          if (std::getenv("MCL_TRACE") != nullptr) {
            std::fprintf(stderr,
                         "global %s seed %d scan %zu err %.3f fit %.3f cons %.3f ratio %.3f low %u inj %u n %u "
                         "sd %.3f m %.3f rad%s\n",
                         d.name.c_str(), seed, er.size() - 1, std::hypot(e.pose.x - s.truth.x, e.pose.y - s.truth.y),
                         e.fit, e.consistency, e.w_fast / e.w_slow, e.low_updates, e.injected, e.particles,
                         std::sqrt(e.covariance[0] + e.covariance[4]), std::sqrt(e.covariance[8]),
                         e.odometry_disagreed ? " scan-incr" : "");
          }
        }
      }
      if (!rack_only()) {
        mrpt::random::getRandomGenerator().randomize(static_cast<uint32_t>(seed));
        MrptReference ref(*d.map, o);
        ref.set_decimation(decimation_for(steps[0], o.beams));
        ref.init_global();
        for (const auto& s : steps) {
          (void)ref.update(s.odometry, s.scan, true);
          em.push_back(ref.estimate());
        }
        nm = ref.particles();
      }
      const double ar = recovered_after<int>(steps, 0, er);
      const double am = rack_only() ? -1.0 : recovered_after<int>(steps, 0, em);
      conv_r += ar >= 0 ? 1 : 0;
      conv_m += am >= 0 ? 1 : 0;
      within += (ar >= 0 && (am < 0 || ar <= 2.0 * std::max(am, 1.0))) ? 1 : 0;
      char buf[96];
      std::snprintf(buf, sizeof buf, "%s%s [%zu]", seed > 1 ? ", " : "",
                    ar < 0 ? "never" : (std::to_string(static_cast<int>(std::lround(ar))) + " m").c_str(), nr);
      rr += buf;
      std::snprintf(buf, sizeof buf, "%s%s [%zu]", seed > 1 ? ", " : "",
                    am < 0 ? "never" : (std::to_string(static_cast<int>(std::lround(am))) + " m").c_str(), nm);
      mm += buf;
    }
    out("| %s | %s | %s | %d / %d of %d | %d of %d |\n", d.name.c_str(), rr.c_str(), mm.c_str(), conv_r, conv_m, seeds,
        within, seeds);
  }
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, perfect = false;
  int global_seeds = 10;
  uint32_t global_particles = 20000;
  std::size_t global_scans = 200;
  int seeds = 3;
  uint32_t particles = 1000;
  std::string json, markdown, only;
  std::string parts = ",track,kidnap,";
  std::vector<KidnapPoint> kidnap_points{KidnapPoint{}};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--seeds" && i + 1 < argc) seeds = std::max(1, std::atoi(argv[++i]));
    else if (a == "--particles" && i + 1 < argc) particles = static_cast<uint32_t>(std::max(1, std::atoi(argv[++i])));
    else if (a == "--datasets" && i + 1 < argc) only = std::string(",") + argv[++i] + ",";
    else if (a == "--parts" && i + 1 < argc) parts = std::string(",") + argv[++i] + ",";
    else if (a == "--json" && i + 1 < argc) json = argv[++i];
    else if (a == "--markdown" && i + 1 < argc) markdown = argv[++i];
    else if (a == "--perfect-odometry") perfect = true;
    else if (a == "--kidnap" && i + 1 < argc) {
      kidnap_points = parse_kidnap_points(argv[++i]);
      if (kidnap_points.empty()) {
        std::fprintf(stderr,
                     "bench_mcl_real: --kidnap %s: expected FROM:TO[,FROM:TO...], fractions of the log "
                     "(a/b or decimals in (0, 1)), FROM before TO\n",
                     argv[i]);
        return 2;
      }
    } else if (a == "--global-seeds" && i + 1 < argc) global_seeds = std::max(1, std::atoi(argv[++i]));
    else if (a == "--global-particles" && i + 1 < argc)
      global_particles = static_cast<uint32_t>(std::max(300, std::atoi(argv[++i])));
    else if (a == "--global-scans" && i + 1 < argc)
      global_scans = static_cast<std::size_t>(std::max(10, std::atoi(argv[++i])));
    else if (a == "-h" || a == "--help") {
      std::printf(
          "bench_mcl_real [--quick] [--seeds N] [--particles N] [--datasets intel,aces,fhw,seattle,sim]\n"
          "               [--parts track,kidnap,global] [--global-seeds N] [--global-particles N]\n"
          "               [--global-scans N] [--json FILE] [--markdown FILE] [--perfect-odometry]\n"
          "               [--kidnap FROM:TO[,FROM:TO...]]\n"
          "  --kidnap: where the kidnap part carries the robot, as fractions of each log (a/b or\n"
          "            decimals), one table per point; default 1/3:2/3\n"
          "  MCL_RACK_ONLY=1: rack's filter alone in the tracking, kidnap and global parts\n"
          "  MCL_TRACE=1: every scan of rack's filter on stderr (after the kidnap: the fit at the\n"
          "               true pose and the particles near it)\n");
      return 0;
    } else {
      std::fprintf(stderr, "bench_mcl_real: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (quick) seeds = std::min(seeds, 2);
  const std::string root = RACK_SOURCE_DIR;
  std::vector<Data> sets;
  for (const char* name : {"intel", "aces", "fhw", "seattle"}) {
    if (!only.empty() && only.find(std::string(",") + name + ",") == std::string::npos) continue;
    Data d;
    d.name = name;
    auto loaded = rack::maps::load_map(root + "/bench/data/carmen/" + name + ".yaml");
    if (!loaded.ok()) {
      std::fprintf(stderr, "bench_mcl_real: %s\n", loaded.error_text().c_str());
      return 1;
    }
    d.map = std::move(loaded.map);
    auto ds = rack::test::load_dataset(root + "/bench/data/carmen/" + name + ".log.gz");
    if (!ds.error.empty()) {
      std::fprintf(stderr, "bench_mcl_real: %s\n", ds.error.c_str());
      return 1;
    }
    d.steps = std::move(ds.steps);
    if (perfect) {
      for (auto& s : d.steps) s.odometry = s.truth;
    }
    sets.push_back(std::move(d));
  }
  if (only.empty() || only.find(",sim,") != std::string::npos) {
    Data d;
    d.name = "sim (office tour)";
    d.real = false;
    auto loaded = rack::maps::load_map(root + "/configs/maps/office.yaml");
    if (!loaded.ok()) {
      std::fprintf(stderr, "bench_mcl_real: %s\n", loaded.error_text().c_str());
      return 1;
    }
    d.map = std::move(loaded.map);
    d.steps = sim_tour(*d.map, 1);
    sets.push_back(std::move(d));
  }
  out("Datasets: ");
  for (const auto& d : sets) out("%s (%zu scans) ", d.name.c_str(), d.steps.size());
  out("\n");
  if (parts.find(",track,") != std::string::npos) part_track(sets, seeds, particles);
  if (parts.find(",kidnap,") != std::string::npos) part_kidnap(sets, seeds, particles, kidnap_points);
  if (parts.find(",global,") != std::string::npos) part_global(sets, global_seeds, global_particles, global_scans);
  if (!markdown.empty()) {
    std::FILE* f = std::fopen(markdown.c_str(), "w");
    if (f != nullptr) {
      std::fputs(g_md.c_str(), f);
      std::fclose(f);
    }
  }
  if (!json.empty()) {
    std::string esc;
    for (char c : g_md) {
      if (c == '"' || c == '\\') esc += '\\';
      if (c == '\n') esc += "\\n";
      else esc += c;
    }
    std::FILE* f = std::fopen(json.c_str(), "w");
    if (f == nullptr) return 1;
    std::fprintf(
        f,
        "{\"title\": \"bench_mcl_real: localisation on real recorded data beside MRPT alone\", \"markdown\": \"%s\"}\n",
        esc.c_str());
    std::fclose(f);
  }
  return 0;
}
