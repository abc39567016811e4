#include "position/position.h"

#include <cmath>

namespace rack::components {

using interfaces::OdometryData;
using interfaces::PositionData;
using interfaces::PositionUpdate;

Position::Position()
    : DataComponent(DataTaskMode::kTriggered),
      odometry_(declare_input<OdometryData>("odometry", {.doc = "the Odometry whose motion carries the pose forward"})),
      initial_x_(declare_float("initial_x", 0.0, {.doc = "m, pose at ON (map frame) until the first UPDATE"})),
      initial_y_(declare_float("initial_y", 0.0, {.doc = "m, pose at ON (map frame)"})),
      initial_phi_(declare_float("initial_phi", 0.0, {.doc = "rad, heading at ON", .min = -7.0, .max = 7.0})),
      initial_var_xy_(declare_float("initial_var_xy", 0.01,
                                    {.doc = "m^2, variance of the initial x and y", .min = 0.0, .max = 1e6})),
      initial_var_phi_(declare_float("initial_var_phi", 0.01,
                                     {.doc = "rad^2, variance of the initial heading", .min = 0.0, .max = 100.0})),
      var_xy_per_m_(declare_float("var_xy_per_m", 0.001,
                                  {.doc = "m^2 of x and y variance added per metre driven", .min = 0.0, .max = 10.0})),
      var_phi_per_m_(
          declare_float("var_phi_per_m", 0.0005,
                        {.doc = "rad^2 of heading variance added per metre driven", .min = 0.0, .max = 10.0})) {}

HookResult Position::on() {  // the data task is idle: its state may be set here
  update_.clear();
  reference_ = Reference{};
  if (published_) {
    // Switched on again (e.g. after its odometry went away and came back): the robot
    // is where it was last seen, not at the initial pose. Motion while off is lost.
    reference_.pose = Pose2d{last_.x, last_.y, last_.phi};
    reference_.var_x = last_.var_x;
    reference_.var_y = last_.var_y;
    reference_.var_phi = last_.var_phi;
  } else {
    reference_.pose = Pose2d{initial_x_.get_float(), initial_y_.get_float(), normalize_angle(initial_phi_.get_float())};
    reference_.var_x = reference_.var_y = initial_var_xy_.get_float();
    reference_.var_phi = initial_var_phi_.get_float();
  }
  return HookResult::kOk;
}

HookResult Position::loop() {
  const Received r = receive([&](const InputPort&) {
    const OdometryData& o = odometry_.value();
    const int64_t time_ns = odometry_.time_ns();
    odometry_resets_.store(o.resets, std::memory_order_relaxed);
    const Pose2d odo{o.x, o.y, o.phi};
    if (Reference u; update_.take(u)) {  // UPDATEs since the last sample: the newest, counted
      u.updates += reference_.updates;
      reference_ = u;
    }
    if (reference_.time_ns == 0) {  // first sample after ON: anchor the initial pose here
      reference_.odometry = odo;
      reference_.distance = o.distance;
      reference_.time_ns = time_ns;
      reference_.resets = o.resets;
    } else if (reference_.resets != o.resets) {
      // RESET: the odometry restarted from zero just before this sample's increment,
      // so the previous pose is the new frame's origin (nothing of this step is lost).
      reference_.pose = Pose2d{last_.x, last_.y, last_.phi};
      reference_.var_x = last_.var_x;
      reference_.var_y = last_.var_y;
      reference_.var_phi = last_.var_phi;
      reference_.odometry = Pose2d{};
      reference_.distance = 0.0;
      reference_.resets = o.resets;
    }
    const Reference& ref = reference_;
    const Pose2d pose = compose(ref.pose, between(ref.odometry, odo));
    const double travelled = std::abs(o.distance - ref.distance);
    last_.x = pose.x;
    last_.y = pose.y;
    last_.phi = pose.phi;
    last_.var_x = ref.var_x + var_xy_per_m_.get_float() * travelled;
    last_.var_y = ref.var_y + var_xy_per_m_.get_float() * travelled;
    last_.var_phi = ref.var_phi + var_phi_per_m_.get_float() * travelled;
    last_.reference_time_ns = ref.updates == 0 ? 0 : ref.time_ns;
    last_.updates = ref.updates;
    publish(last_, time_ns);
    published_ = true;
  });
  return r.failed ? HookResult::kError : HookResult::kOk;  // the odometry left ENABLED or fell silent
}

void Position::handle_update(const tims::MessageHeader& request, std::span<const std::byte> body) noexcept {
  PositionUpdate u;
  if (!wire::read_payload(body, tims::body_is_native(request), u)) {
    return reject_malformed(request, "UPDATE: body must be a PositionUpdate (time and 6 doubles)");
  }
  if (u.time_ns <= 0 || !std::isfinite(u.x) || !std::isfinite(u.y) || !std::isfinite(u.phi) ||
      !std::isfinite(u.var_x) || !std::isfinite(u.var_y) || !std::isfinite(u.var_phi) || u.var_x < 0.0 ||
      u.var_y < 0.0 || u.var_phi < 0.0) {
    return reject_malformed(request, "UPDATE: time must be > 0, pose finite, variances >= 0");
  }
  if (state() != ComponentState::kEnabled) return reply_error(request, "UPDATE: position not enabled");
  // The odometry at the update's time, not now: the pose refers to that moment.
  wire::GetDataRequest get;
  get.time_ns = u.time_ns;
  alignas(8) std::byte buf[sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + sizeof(OdometryData) + 160];
  const auto r = command_endpoint().call(odometry_.source(), tims::msg::kGetData, get, std::span<std::byte>(buf),
                                         settings().rpc_timeout_ns);
  wire::SampleHeader sh;
  OdometryData o;
  if (r.status != tims::CallStatus::kOk || r.reply.type != tims::msg::kData || !read_sample(r.reply, r.body, sh, o)) {
    wire::ErrorText text;
    wire::copy_text(text.text, "UPDATE: no odometry at that time: ");
    if (r.status != tims::CallStatus::kOk) {
      wire::append_text(text.text, tims::describe(r.status));
    } else if (r.reply.type == tims::msg::kError && !r.body.empty()) {
      char reason[sizeof text.text] = {};
      const std::size_t n = r.body.size() < sizeof reason - 1 ? r.body.size() : sizeof reason - 1;
      std::memcpy(reason, r.body.data(), n);
      wire::append_text(text.text, reason);
    } else {
      wire::append_text(text.text, "unexpected reply");
    }
    return reply_with(request, tims::msg::kError, text);
  }
  if (o.resets != odometry_resets_.load(std::memory_order_relaxed)) {
    return reply_error(request, "UPDATE: the odometry was RESET after that time");
  }
  // The ring holds the nearest sample; carry it to the exact time with its velocities.
  const double dt = static_cast<double>(u.time_ns - sh.time_ns) * 1e-9;
  const Pose2d odo = compose(Pose2d{o.x, o.y, o.phi}, integrate_twist(o.vx, 0.0, o.omega, dt));
  update_.post([&](Reference& ref) {  // the data task takes it with the next odometry sample
    ref.pose = Pose2d{u.x, u.y, normalize_angle(u.phi)};
    ref.odometry = odo;
    ref.distance = o.distance;
    ref.var_x = u.var_x;
    ref.var_y = u.var_y;
    ref.var_phi = u.var_phi;
    ref.time_ns = u.time_ns;
    ref.resets = o.resets;
    ++ref.updates;  // UPDATEs since the data task last took one
  });
  reply(request, tims::msg::kOk);
}

CommandResult Position::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kPositionUpdate) return CommandResult::kUnknown;
  handle_update(request, body);
  return CommandResult::kHandled;
}

}  // namespace rack::components
