#include "mcl.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>

#include "rack/maps/occupancy_map.h"
#include "rack/mcl/mcl_filter.h"

namespace rack::components {

using interfaces::MclData;
using interfaces::Scan2dData;

namespace {

// "x y phi" or "x, y, phi" (metres, metres, radians). RT-safe (strtod, no allocation).
bool parse_pose(const char* text, double& x, double& y, double& phi) noexcept {
  double v[3] = {};
  const char* p = text;
  for (double& out : v) {
    while (*p == ' ' || *p == ',' || *p == '\t' || *p == '[') ++p;
    char* end = nullptr;
    out = std::strtod(p, &end);
    if (end == p || !std::isfinite(out)) return false;
    p = end;
  }
  while (*p == ' ' || *p == ']' || *p == '\t') ++p;
  if (*p != '\0') return false;
  x = v[0];
  y = v[1];
  phi = v[2];
  return true;
}
}  // namespace

Mcl::Mcl()
    : DataComponent(DataTaskMode::kTriggered),
      map_(declare_string(
          "map", "",
          {.doc = "map_server YAML file of the map (relative: to the host file's folder, e.g. maps/office.yaml)",
           .required = true,
           .init_only = true,
           .path = PathRole::kInput})),
      scan2d_(declare_input<Scan2dData>("scan2d", {.doc = "the Scan2D component whose scans (with odometry) MCL uses",
                                                   .ask_period = true,
                                                   .old_period_name = "period_ms"})),
      position_(declare_string("position", "",
                               {.doc = "Position component to send UPDATE to (optional; empty: none)",
                                .component_ref = true})),
      particles_min_(
          declare_int("particles_min", 100, {.doc = "KLD-sampling: fewest particles", .min = 1, .max = 1e6})),
      particles_max_(
          declare_int("particles_max", 2000,
                      {.doc = "KLD-sampling: most particles (also the count after an init)", .min = 1, .max = 1e6})),
      initial_pose_(
          declare_string("initial_pose", "0 0 0",
                         {.doc = "start pose 'x y phi' (m, m, rad) in the map frame, used when global is false"})),
      initial_sigma_xy_(declare_float("initial_sigma_xy", 0.3,
                                      {.doc = "spread (std dev, m) around initial_pose", .min = 0.0, .max = 1e3})),
      initial_sigma_phi_(declare_float("initial_sigma_phi", 0.2,
                                       {.doc = "spread (std dev, rad) around initial_pose", .min = 0.0, .max = 10.0})),
      global_(declare_bool("global", false, {.doc = "start with global localisation over the map's free space"})),
      global_candidates_(declare_int(
          "global_candidates", 5,
          {.doc =
               "global start: the first scan weighs this many times particles_max poses over the free space and keeps the particles_max that fit best (more: surer to find the place, one costlier update); recovery likewise injects the best of this many random poses per injected particle",
           .min = 1,
           .max = 100})),
      update_distance_(declare_float("update_distance", 0.10,
                                     {.doc = "run the filter after this much travel (m)", .min = 0.0, .max = 100.0})),
      update_angle_(
          declare_float("update_angle", 0.10, {.doc = "... or this much turn (rad)", .min = 0.0, .max = 10.0})),
      odometry_jump_(declare_float(
          "odometry_jump", 5.0,
          {.doc =
               "an odometry increment longer than this between two consecutive scans is a jump (RESET): that increment is dropped, the motion before it kept (m; 0: off)",
           .min = 0.0,
           .max = 1e3})),
      beams_(declare_int("beams", 60,
                         {.doc = "scan points used per update, evenly chosen (0: all)", .min = 0, .max = 100000})),
      sigma_hit_(declare_float(
          "sigma_hit", 0.10,
          {.doc =
               "likelihood field: std dev of a point's distance to the nearest wall (m): sensor noise plus map error",
           .min = 1e-3,
           .max = 10.0})),
      max_range_(declare_float(
          "max_range", 30.0,
          {.doc = "likelihood field: support of the random-reading term (m)", .min = 0.1, .max = 1000.0})),
      max_corr_distance_(declare_float(
          "max_corr_distance", 0.5,
          {.doc =
               "likelihood field: distances to a wall beyond this count as this far; also for points outside the map (m)",
           .min = 0.01,
           .max = 100.0})),
      odom_a1_(declare_float(
          "odom_a1", 0.20,
          {.doc = "motion model: translation std dev per metre travelled (m/m; MRPT's a1)", .min = 0.0, .max = 10.0})),
      odom_a2_(declare_float(
          "odom_a2", 0.001,
          {.doc = "motion model: translation std dev per radian turned (m/rad; MRPT's a2)", .min = 0.0, .max = 10.0})),
      odom_a3_(declare_float(
          "odom_a3", 0.05,
          {.doc = "motion model: heading std dev per metre travelled (rad/m; MRPT's a3)", .min = 0.0, .max = 10.0})),
      odom_a4_(declare_float(
          "odom_a4", 0.05,
          {.doc = "motion model: heading std dev per radian turned (rad/rad; MRPT's a4)", .min = 0.0, .max = 10.0})),
      odom_min_std_xy_(
          declare_float("odom_min_std_xy", 0.01,
                        {.doc = "motion model: least translation std dev per update (m)", .min = 0.0, .max = 10.0})),
      odom_min_std_phi_(
          declare_float("odom_min_std_phi", 0.01,
                        {.doc = "motion model: least heading std dev per update (rad)", .min = 0.0, .max = 10.0})),
      odom_outlier_fraction_(declare_float(
          "odom_outlier_fraction", 0.10,
          {.doc =
               "motion model: fraction of particles moved with odom_outlier_scale times the noise (odometry that stalls or slips; 0: off)",
           .min = 0.0,
           .max = 1.0})),
      odom_outlier_scale_(
          declare_float("odom_outlier_scale", 3.0,
                        {.doc = "motion model: noise factor for that fraction", .min = 1.0, .max = 1000.0})),
      odometry_check_(declare_float(
          "odometry_check", 2.0,
          {.doc =
               "odometry check: each update matches the scan against the previous update's (ICP); when that increment differs from the odometry's by more than this many motion-model std devs, part of the particles moves by the scan's increment (odometry that stalls and catches up; 0: off)",
           .min = 0.0,
           .max = 100.0})),
      odometry_check_fraction_(declare_float(
          "odometry_check_fraction", 0.5,
          {.doc = "odometry check: share of the particles moved by the scan's increment when it disagrees",
           .min = 0.0,
           .max = 1.0})),
      odometry_check_goodness_(
          declare_float("odometry_check_goodness", 0.5,
                        {.doc = "odometry check: least share of the scan's points the match must pair to be trusted",
                         .min = 0.01,
                         .max = 1.0})),
      recovery_ratio_(
          declare_float("recovery_ratio", 0.5,
                        {.doc = "recovery: lost when the short-term scan fit is below this times the long-term one ...",
                         .min = 0.01,
                         .max = 0.99})),
      recovery_consistency_(declare_float(
          "recovery_consistency", 0.9,
          {.doc = "... and the short-term share of beams not through a wall is below this times the long-term one ...",
           .min = 0.01,
           .max = 1.0})),
      recovery_updates_(declare_int(
          "recovery_updates", 5,
          {.doc = "... for this many updates in a row: then random particles are injected", .min = 1, .max = 1000})),
      inject_max_fraction_(declare_float(
          "inject_max_fraction", 0.50,
          {.doc =
               "recovery: most random particles added per update while lost, as a fraction of particles_max (0: no recovery)",
           .min = 0.0,
           .max = 1.0})),
      fit_min_(declare_float(
          "fit_min", 0.0,
          {.doc =
               "recovery: also lost while the short-term scan fit (MclData.fit) stays below this (0: off; clutter lowers the fit)",
           .min = 0.0,
           .max = 0.99})),
      alpha_slow_(
          declare_float("alpha_slow", 0.01, {.doc = "recovery: long-term average rate", .min = 1e-6, .max = 1.0})),
      alpha_fast_(declare_float("alpha_fast", 0.2,
                                {.doc = "recovery: short-term average rate (> alpha_slow)", .min = 1e-6, .max = 1.0})),
      threads_(declare_int(
          "threads", 2,
          {.doc =
               "threads evaluating the scan likelihood (1 or 2: the data task and a compute worker with its priority and CPUs, for updates of at least 100000 particles x points)",
           .min = 1,
           .max = 2,
           .init_only = true})),
      seed_(declare_int("seed", 0, {.doc = "random seed (0: from the clock)", .min = 0, .max = 4294967295.0})),
      show_particles_(declare_int(
          "show_particles", 100,
          {.doc = "particles published per sample (at most 256)", .min = 0, .max = interfaces::kMclMaxShownParticles})),
      position_max_std_(declare_float(
          "position_max_std", 0.5,
          {.doc = "send Position UPDATE only when the position std dev is below this (m)", .min = 0.0, .max = 1e3})) {
  set_command_slot_size(1024);
}

Mcl::~Mcl() = default;

mcl::MclOptions Mcl::read_options(const ParameterValues& v) const noexcept {
  mcl::MclOptions o;
  o.particles_min = static_cast<uint32_t>(v.get_int(particles_min_));
  o.particles_max = static_cast<uint32_t>(v.get_int(particles_max_));
  o.update_distance = v.get_float(update_distance_);
  o.update_angle = v.get_float(update_angle_);
  o.beams = static_cast<uint32_t>(v.get_int(beams_));
  o.odometry_jump = v.get_float(odometry_jump_);
  o.sigma_hit = v.get_float(sigma_hit_);
  o.max_range = v.get_float(max_range_);
  o.max_corr_distance = v.get_float(max_corr_distance_);
  o.odom_a1 = v.get_float(odom_a1_);
  o.odom_a2 = v.get_float(odom_a2_);
  o.odom_a3 = v.get_float(odom_a3_);
  o.odom_a4 = v.get_float(odom_a4_);
  o.odom_min_std_xy = v.get_float(odom_min_std_xy_);
  o.odom_min_std_phi = v.get_float(odom_min_std_phi_);
  o.odom_outlier_fraction = v.get_float(odom_outlier_fraction_);
  o.odom_outlier_scale = v.get_float(odom_outlier_scale_);
  o.odometry_check = v.get_float(odometry_check_);
  o.odometry_check_fraction = v.get_float(odometry_check_fraction_);
  o.odometry_check_goodness = v.get_float(odometry_check_goodness_);
  o.global_candidates = static_cast<uint32_t>(v.get_int(global_candidates_));
  o.recovery_ratio = v.get_float(recovery_ratio_);
  o.recovery_consistency = v.get_float(recovery_consistency_);
  o.recovery_updates = static_cast<uint32_t>(v.get_int(recovery_updates_));
  o.inject_max_fraction = v.get_float(inject_max_fraction_);
  o.fit_min = v.get_float(fit_min_);
  o.alpha_slow = v.get_float(alpha_slow_);
  o.alpha_fast = v.get_float(alpha_fast_);
  o.threads = static_cast<uint32_t>(v.get_int(threads_));
  o.seed = static_cast<uint64_t>(v.get_int(seed_));
  return o;
}

bool Mcl::check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept {
  char pose[wire::kParamStringLen];
  values.copy_string(initial_pose_, pose, sizeof pose);
  double x = 0, y = 0, phi = 0;
  if (!parse_pose(pose, x, y, phi)) {
    problem.set(initial_pose_, "not 'x y phi' (three finite numbers: m, m, rad)");
    return false;
  }
  if (const char* why = mcl::check_options(read_options(values))) {
    // The rule names its parameters; the one being changed is the one at fault.
    problem.set(values.changing() != nullptr ? *values.changing() : particles_max_, why);
    return false;
  }
  return true;
}

void Mcl::init() {
  const std::string path = map_.get_string();
  maps::LoadMapResult loaded = maps::load_map(path);
  if (!loaded.ok()) throw std::runtime_error("map: " + loaded.error_text());
  // initial_pose and the filter's options were checked (check_parameters, before init()).
  const mcl::MclOptions options = read_options();
  // The likelihood's second thread: the executor's, beside the data task (its priority
  // and CPUs); threads is read here only (init_only).
  ComputeWorker* worker = options.threads > 1 ? &add_compute_worker("likelihood") : nullptr;
  filter_ = std::make_unique<mcl::MclFilter>(*loaded.map, options, worker);
  out_ = std::make_unique<MclData>();
  xs_ = std::make_unique<float[]>(interfaces::kScan2dMaxPoints);
  ys_ = std::make_unique<float[]>(interfaces::kScan2dMaxPoints);
  log_info("map %s (%d x %d cells of %.3f m), particles %u..%u", path, loaded.map->width(), loaded.map->height(),
           loaded.map->resolution(), options.particles_min, options.particles_max);
}

HookResult Mcl::on() {
  reinit_.store(true, std::memory_order_release);
  return HookResult::kOk;
}

CommandResult Mcl::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kMclInit) return CommandResult::kUnknown;
  interfaces::MclInit init;
  if (!wire::read_payload(body, tims::body_is_native(request), init)) {
    reject_malformed(request, "INIT: body must be an MclInit (56 bytes)");
    return CommandResult::kHandled;
  }
  if (!std::isfinite(init.x) || !std::isfinite(init.y) || !std::isfinite(init.phi) || !(init.sigma_xy >= 0) ||
      !(init.sigma_phi >= 0) || !std::isfinite(init.sigma_xy) || !std::isfinite(init.sigma_phi)) {
    reject_malformed(request, "INIT: pose must be finite and spreads >= 0");
    return CommandResult::kHandled;
  }
  init_.post(init);
  reply(request, tims::msg::kOk);
  return CommandResult::kHandled;
}

bool Mcl::apply_init() {
  interfaces::MclInit init;
  bool have = init_.take(init);
  if (reinit_.exchange(false, std::memory_order_acquire) && !have) {
    // ON: from the parameters (they may have been changed with SET_PARAM).
    filter_->set_options(read_options());
    if (global_.get_bool()) {
      init.global = 1;
    } else {
      char pose[wire::kParamStringLen];
      initial_pose_.copy_string(pose, sizeof pose);
      if (!parse_pose(pose, init.x, init.y, init.phi)) return false;
      init.sigma_xy = initial_sigma_xy_.get_float();
      init.sigma_phi = initial_sigma_phi_.get_float();
    }
    have = true;
  }
  if (!have) return true;
  if (init.global != 0) filter_->init_global();
  else filter_->init_pose({init.x, init.y, init.phi}, init.sigma_xy, init.sigma_phi);
  updates_since_init_ = 0;
  localisation_ = Localisation::kUnknown;  // a new estimate: the next convergence is said again
  was_lost_ = false;
  lost_updates_ = 0;
  return true;
}

HookResult Mcl::loop() {
  // Only the newest scan counts: the odometry in each scan is absolute, so skipping
  // older ones loses nothing but keeps MCL from lagging behind.
  const Received r = receive([](const InputPort&) {});
  if (r.failed) return HookResult::kError;  // Scan2D left ENABLED or fell silent: re-subscribe on retry
  if (r.samples == 0) return HookResult::kOk;
  const wire::SampleHeader sh = scan2d_.sample_header();
  scans_.fetch_add(1, std::memory_order_relaxed);
  try {
    if (!apply_init()) return HookResult::kError;
    const Scan2dData& s = scan2d_.value();
    if (s.odometry_valid == 0) {  // no motion model without odometry: wait for the next
      if (no_odometry_.fetch_add(1, std::memory_order_relaxed) == 0) {
        log_warning(
            "scans carry no odometry (odometry_valid 0); give the Scan2D component an 'odometry' parameter. Such "
            "scans are skipped.");
      }
      return HookResult::kOk;
    }
    std::size_t n = 0;
    const std::size_t count = std::min<std::size_t>(s.point_count, interfaces::kScan2dMaxPoints);
    for (std::size_t i = 0; i < count; ++i) {
      if (s.type[i] == interfaces::kScanPointMaxRange) continue;  // no echo: says nothing about walls
      xs_[n] = s.x[i];
      ys_[n] = s.y[i];
      ++n;
    }
    const bool ran = filter_->update({s.odometry_x, s.odometry_y, s.odometry_phi}, std::span<const float>(xs_.get(), n),
                                     std::span<const float>(ys_.get(), n));
    if (ran) ++updates_since_init_;
    const mcl::MclEstimate e = filter_->estimate();
    MclData& d = *out_;
    d.x = e.pose.x;
    d.y = e.pose.y;
    d.phi = e.pose.phi;
    for (int i = 0; i < 9; ++i) d.covariance[i] = e.covariance[i];
    d.scan_time_ns = sh.time_ns;
    d.particle_count = e.particles;
    d.updates = updates_since_init_;
    d.effective_sample_size = e.ess;
    d.injected = e.injected;
    d.fit = static_cast<float>(e.fit);
    const auto shown = static_cast<std::size_t>(show_particles_.get_int());
    d.shown = static_cast<uint32_t>(
        filter_->sample_particles(std::span<float>(d.particle_x, shown), std::span<float>(d.particle_y, shown),
                                  std::span<float>(d.particle_phi, shown), std::span<float>(d.particle_weight, shown)));
    publish(d, sh.time_ns);
    if (ran) {
      send_position_update(sh.time_ns);
      report_localisation(d);
    }
  } catch (const std::exception& e) {
    log_error("update failed: %s", e.what());
    return HookResult::kError;
  }
  return HookResult::kOk;
}

void Mcl::report_localisation(const MclData& d) noexcept {
  const double std_xy = std::sqrt(std::max(0.0, d.covariance[0] + d.covariance[4]));
  Localisation now = localisation_;
  if (d.injected > 0) now = Localisation::kLost;  // recovery injects random particles
  else if (std_xy <= position_max_std_.get_float()) now = Localisation::kConverged;
  else if (localisation_ == Localisation::kConverged) now = Localisation::kUncertain;
  if (now == Localisation::kLost) ++lost_updates_;
  if (now == localisation_) return;
  const Localisation before = localisation_;
  localisation_ = now;
  const int64_t t = rt::monotonic_ns();
  if (last_event_ns_ != 0 && t - last_event_ns_ < kEventEveryNs) {  // rate limit: counted
    ++events_unlogged_;
    if (now == Localisation::kLost) was_lost_ = true;
    return;
  }
  last_event_ns_ = t;
  const unsigned unlogged = events_unlogged_;
  events_unlogged_ = 0;
  switch (now) {
    case Localisation::kLost:
      was_lost_ = true;
      log_info(
          "lost: the scans no longer fit the map (fit %.2f, std %.2f m); recovering: %u random particles "
          "injected (%u changes not logged)",
          static_cast<double>(d.fit), std_xy, static_cast<unsigned>(d.injected), unlogged);
      break;
    case Localisation::kConverged:
      if (was_lost_ || before == Localisation::kLost) {
        log_info("re-localised at (%.2f, %.2f, %.2f rad), std %.2f m, after %u updates lost (%u changes not logged)",
                 d.x, d.y, d.phi, std_xy, static_cast<unsigned>(lost_updates_), unlogged);
      } else {
        log_info("converged at (%.2f, %.2f, %.2f rad), std %.2f m, after %u updates (%u changes not logged)", d.x, d.y,
                 d.phi, std_xy, static_cast<unsigned>(d.updates), unlogged);
      }
      was_lost_ = false;
      lost_updates_ = 0;
      break;
    case Localisation::kUncertain:
      log_info("uncertain: std %.2f m, above position_max_std (Position gets no updates) (%u changes not logged)",
               std_xy, unlogged);
      break;
    case Localisation::kUnknown: break;
  }
}

void Mcl::send_position_update(int64_t time_ns) noexcept {
  const tims::Address position = resolved(position_);
  if (position.raw() == 0) return;  // no Position configured
  const MclData& d = *out_;
  const double std_xy = std::sqrt(std::max(0.0, d.covariance[0] + d.covariance[4]));
  if (!(std_xy <= position_max_std_.get_float())) return;  // not localised yet
  interfaces::PositionUpdate u;
  u.time_ns = time_ns;
  u.x = d.x;
  u.y = d.y;
  u.phi = d.phi;
  u.var_x = d.covariance[0];
  u.var_y = d.covariance[4];
  u.var_phi = d.covariance[8];
  alignas(8) std::byte buf[512];
  const auto r = data_endpoint().call(position, interfaces::kPositionUpdate, u, std::span<std::byte>(buf),
                                      settings().rpc_timeout_ns);
  (r.ok() ? position_ok_ : position_failed_).fetch_add(1, std::memory_order_relaxed);
}

}  // namespace rack::components
