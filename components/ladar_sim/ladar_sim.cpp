#include "ladar_sim/ladar_sim.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace rack::components {

using interfaces::ChassisData;
using interfaces::LadarData;

LadarSim::LadarSim()
    : DataComponent(DataTaskMode::kPeriodic),
      map_(declare_string("map", "", {.doc = "map_server YAML file (path relative to rackd's working directory)", .required = true})),
      chassis_(declare_component_ref("chassis", "the simulated Chassis whose true pose the scans are rendered from")),
      mount_x_(declare_float("mount_x", 0.0, {.doc = "m, sensor position in the robot frame (forward)", .min = -10.0, .max = 10.0})),
      mount_y_(declare_float("mount_y", 0.0, {.doc = "m, sensor position in the robot frame (left)", .min = -10.0, .max = 10.0})),
      mount_phi_(declare_float("mount_phi", 0.0, {.doc = "rad, sensor heading in the robot frame", .min = -7.0, .max = 7.0})),
      beams_(declare_int("beams", 541, {.doc = "beams per scan", .min = 2, .max = interfaces::kLadarMaxBeams})),
      fov_deg_(declare_float("fov_deg", 270.0, {.doc = "field of view, centred on the sensor's axis", .min = 1.0, .max = 360.0})),
      range_min_(declare_float("range_min", 0.05, {.doc = "m, the sensor's blind zone", .min = 0.0, .max = 100.0})),
      range_max_(declare_float("range_max", 20.0, {.doc = "m, no echo beyond", .min = 0.1, .max = 1000.0})),
      noise_sigma_(declare_float("noise_sigma", 0.01, {.doc = "m, std-dev of gaussian range noise", .min = 0.0, .max = 10.0})),
      seed_(declare_int("seed", 2, {.doc = "seed of the noise generator", .min = 0, .max = 1e15})),
      silence_ms_(declare_int("silence_ms", 1000, {.doc = "ERROR when the chassis sent no pose for this long", .min = 10, .max = 60000})) {
  use_input_mailbox(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(ChassisData) + 64);
}

void LadarSim::init() {
  const std::string path = map_.get_string();
  auto loaded = maps::load_map(path);
  if (!loaded.ok()) throw std::runtime_error("map: " + loaded.error_text());
  map_data_ = std::move(loaded.map);
  rng_.seed(static_cast<uint64_t>(seed_.get_int()));
}

HookResult LadarSim::on() {
  have_truth_ = false;
  published_time_ns_ = 0;
  last_truth_mono_ns_ = rt::monotonic_ns();
  const tims::Address chassis = resolved(chassis_);
  if (switch_on(chassis) != HookResult::kOk) return HookResult::kError;
  return subscribe(chassis, 0);
}

void LadarSim::off() { unsubscribe(resolved(chassis_)); }

HookResult LadarSim::loop() {
  const int64_t now = rt::monotonic_ns();
  for (;;) {  // keep the newest true pose
    wire::SampleHeader sh;
    ChassisData c;
    const Input in = next_sample(sh, c);
    if (in == Input::kNone) break;
    if (in == Input::kError) return HookResult::kError;  // the chassis left ENABLED
    if (c.truth_valid == 0) continue;
    truth_ = Pose2d{c.truth_x, c.truth_y, c.truth_phi};
    truth_time_ns_ = sh.time_ns;
    last_truth_mono_ns_ = now;
    have_truth_ = true;
  }
  if (now - last_truth_mono_ns_ > silence_ms_.get_int() * rt::kNsPerMs) return HookResult::kError;
  // Nothing to render from yet, or no new pose since the last scan (one scan per pose).
  if (!have_truth_ || truth_time_ns_ == published_time_ns_) return HookResult::kOk;

  const Pose2d sensor = compose(truth_, Pose2d{mount_x_.get_float(), mount_y_.get_float(), mount_phi_.get_float()});
  const auto n = static_cast<uint32_t>(beams_.get_int());
  const double fov = fov_deg_.get_float() * std::numbers::pi / 180.0;
  // A full circle must not render its first direction twice.
  const double step = fov >= 2.0 * std::numbers::pi - 1e-9 ? fov / n : fov / (n - 1);
  const double start = -fov / 2.0;
  const double range_max = range_max_.get_float();
  const double range_min = range_min_.get_float();
  const double sigma = noise_sigma_.get_float();
  scan_.duration_ns = 0;  // rendered at one instant
  scan_.max_range = static_cast<float>(range_max);
  scan_.min_range = static_cast<float>(range_min);
  scan_.start_angle = static_cast<float>(start);
  scan_.angle_step = static_cast<float>(step);
  scan_.beam_count = n;
  for (uint32_t i = 0; i < n; ++i) {
    const double a = sensor.phi + start + static_cast<double>(i) * step;
    const maps::RayHit hit = map_data_->cast_ray(sensor.x, sensor.y, a, range_max);
    double r = 0.0;  // no echo
    if (hit.hit) {
      r = static_cast<double>(hit.range) + (sigma > 0.0 ? sigma * normal_(rng_) : 0.0);
      if (r < range_min) r = range_min;
      if (r > range_max) r = 0.0;
    }
    scan_.range[i] = static_cast<float>(r);
    scan_.intensity[i] = hit.hit ? 1.0F : 0.0F;
  }
  publish(scan_, truth_time_ns_);
  published_time_ns_ = truth_time_ns_;
  return HookResult::kOk;
}

}  // namespace rack::components
