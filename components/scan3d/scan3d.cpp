#include "scan3d/scan3d.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iterator>
#include <stdexcept>

#include "rack/components/class_ids.h"
#include "rack/scan3d/pcd_file.h"
#include "rack/scan3d/scan3d_assembler.h"
#include "rack/scan3d/scan3d_pipeline.h"

namespace rack::components {

using interfaces::LadarData;
using interfaces::OdometryData;
using interfaces::PositionData;
using interfaces::Scan3dData;
using interfaces::ServoDriveData;

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}  // namespace

Scan3d::Scan3d()
    : DataComponent(DataTaskMode::kTriggered),
      // Declared inputs (none configured with pcd). Their silence is checked in loop()
      // (each source by name, also a pose that covers no scan) against silence_ms,
      // Scan3D's own parameter before the inputs were declared: data_task.timeout_ms
      // stays the triggered task's wake-up.
      ladar_(
          declare_input<LadarData>("ladar", {.doc = "the Ladar whose 2-D scans are assembled (with servo; empty: pcd)",
                                             .optional = true,
                                             .watched = false,
                                             .silence_ms = 2000.0,
                                             .silence_param = SilenceParam::kSilenceMsOnly})),
      servo_(declare_input<ServoDriveData>("servo", {.doc = "the ServoDrive that turns the ladar (with ladar)",
                                                     .optional = true,
                                                     .ask_period = true,
                                                     .watched = false})),
      // The last 256 poses must cover a sweep's processing time (odometry_period_ms).
      odometry_(declare_input<OdometryData, PositionData>(
          "odometry",
          {.doc = "with ladar+servo: an Odometry or Position component; its poses undo the robot's motion during a "
                  "sweep (points in the robot frame at the sweep's end, the scan stamped with that time)",
           .optional = true,
           .ask_period = true,
           .watched = false})),
      pcd_(declare_string(
          "pcd", "",
          {.doc = "instead of ladar+servo: a PCD file, or a directory whose *.pcd files are played in name order",
           .init_only = true,
           .path = PathRole::kInput})),
      mode_(declare_string("mode", "pitch",
                           {.doc = "scan mode: the drive turns the scan plane about x (roll), y (pitch) or z (yaw)",
                            .choices = {"roll", "pitch", "yaw"},
                            .init_only = true})),
      mount_x_(declare_float(
          "mount_x", 0.0,
          {.doc = "m, the ladar's centre (on the drive axis) in the robot frame, forward", .min = -10.0, .max = 10.0})),
      mount_y_(declare_float("mount_y", 0.0, {.doc = "m, ... left", .min = -10.0, .max = 10.0})),
      mount_z_(declare_float("mount_z", 0.5, {.doc = "m, ... above the floor", .min = -10.0, .max = 10.0})),
      angle_min_(declare_float("angle_min", -0.5,
                               {.doc = "rad, drive angle where a sweep starts or ends", .min = -10.0, .max = 10.0})),
      angle_max_(
          declare_float("angle_max", 0.5, {.doc = "rad, the other end (> angle_min)", .min = -10.0, .max = 10.0})),
      sweep_velocity_(declare_float(
          "sweep_velocity", 0.5,
          {.doc = "rad/s, drive speed during a sweep (0: the drive's default)", .min = 0.0, .max = 100.0})),
      angle_tolerance_(
          declare_float("angle_tolerance", 0.01,
                        {.doc = "rad, the drive is at a sweep's end when this close", .min = 1e-5, .max = 1.0})),
      range_min_(
          declare_float("range_min", 0.05,
                        {.doc = "m, closer echoes are dropped (the robot, the drive)", .min = 0.0, .max = 1000.0})),
      range_max_(declare_float(
          "range_max", 0.0, {.doc = "m, farther echoes are dropped (0: the ladar's max)", .min = 0.0, .max = 1000.0})),
      voxel_size_(declare_float("voxel_size", 0.05,
                                {.doc = "m, voxel-grid leaf (0: no downsampling)", .min = 0.0, .max = 10.0})),
      outlier_neighbours_(
          declare_int("outlier_neighbours", 16,
                      {.doc = "statistical outlier removal: neighbours (0: off)", .min = 0, .max = 1000})),
      outlier_std_(
          declare_float("outlier_std", 2.0,
                        {.doc = "... remove points farther than mean + this * std dev", .min = 0.01, .max = 100.0})),
      ground_tolerance_(declare_float(
          "ground_tolerance", 0.05,
          {.doc = "m, RANSAC inlier distance; points this close to the plane are ground", .min = 1e-4, .max = 10.0})),
      ground_max_tilt_(declare_float(
          "ground_max_tilt", 0.2,
          {.doc = "rad, the ground plane's normal may be this far from vertical", .min = 1e-3, .max = 1.4})),
      ground_max_height_(declare_float("ground_max_height", 0.3,
                                       {.doc = "m, ground candidates have |z| below this", .min = 1e-3, .max = 100.0})),
      ceiling_height_(
          declare_float("ceiling_height", 0.0,
                        {.doc = "m above the ground: higher points are ceiling (0: none)", .min = 0.0, .max = 1000.0})),
      max_points_(declare_int(
          "max_points", interfaces::kScan3dMaxPoints,
          {.doc = "points per published scan (evenly thinned above)", .min = 1, .max = interfaces::kScan3dMaxPoints})),
      range_image_res_deg_(
          declare_float("range_image_res_deg", 1.0,
                        {.doc = "GET_RANGE_IMAGE: degrees per pixel when the request gives none (at least 0.2)",
                         .min = 0.2,
                         .max = 45.0,
                         .unit = "deg"})),
      store_dir_(declare_string(
          "store_dir", ".",
          {.doc =
               "STORE_DATA without a path writes <store_dir>/scan3d_<number>.pcd (relative: to the host file's folder)",
           .path = PathRole::kOutputDir})),
      pcd_period_ms_(
          declare_float("pcd_period_ms", 1000.0,
                        {.doc = "PCD source: one file every this long (the data task's timeout_ms must not be longer)",
                         .min = 1.0,
                         .max = 3.6e6,
                         .unit = "ms"})),
      pcd_loop_(declare_bool("pcd_loop", true, {.doc = "PCD source: start again after the last file"})),
      sweep_timeout_s_(declare_float("sweep_timeout_s", 30.0,
                                     {.doc = "ERROR when the drive does not reach a sweep's end within this",
                                      .min = 0.1,
                                      .max = 3600.0,
                                      .unit = "s"})) {
  set_command_slot_size(sizeof(tims::MessageHeader) + sizeof(interfaces::Scan3dStoreData) + 64);
}

Scan3d::~Scan3d() = default;

scan3d::PipelineOptions Scan3d::read_options(const ParameterValues& v) const noexcept {
  scan3d::PipelineOptions o;
  o.voxel_size = v.get_float(voxel_size_);
  o.outlier_neighbours = static_cast<int>(v.get_int(outlier_neighbours_));
  o.outlier_std = v.get_float(outlier_std_);
  o.ground_tolerance = v.get_float(ground_tolerance_);
  o.ground_max_tilt = v.get_float(ground_max_tilt_);
  o.ground_max_height = v.get_float(ground_max_height_);
  o.ceiling_height = v.get_float(ceiling_height_);
  o.max_points = static_cast<uint32_t>(v.get_int(max_points_));
  return o;
}

bool Scan3d::check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept {
  if (const char* why = scan3d::check_options(read_options(values))) {
    problem.set(values.changing() != nullptr ? *values.changing() : voxel_size_, why);
    return false;
  }
  if (!(values.get_float(angle_max_) > values.get_float(angle_min_))) {
    problem.set(values.changing() == &angle_min_ ? angle_min_ : angle_max_, "angle_max must be above angle_min");
    return false;
  }
  return true;
}

void Scan3d::init() {
  const std::string pcd = pcd_.get_string();
  const bool have_ladar = !ladar_.source_parameter().get_string().empty();
  const bool have_servo = !servo_.source_parameter().get_string().empty();
  if (!pcd.empty() && (have_ladar || have_servo)) {
    throw std::runtime_error("give either 'pcd' or both 'ladar' and 'servo', not both");
  }
  if (pcd.empty() && !(have_ladar && have_servo)) {
    throw std::runtime_error("give either 'pcd' (files) or both 'ladar' and 'servo' (a ladar on a drive)");
  }
  file_source_ = !pcd.empty();
  const Parameter& odometry = odometry_.source_parameter();
  compensate_ = !odometry.get_string().empty();
  if (file_source_ && compensate_)
    throw std::runtime_error("'odometry' compensates a ladar on a drive: it needs 'ladar' and 'servo', not 'pcd'");
  if (compensate_) {
    const uint8_t c = resolved(odometry).class_id();
    if (c != class_ids::kOdometry && c != class_ids::kPosition) {
      throw std::runtime_error("odometry '" + odometry.get_string() + "' is " + resolved(odometry).str() +
                               ", neither an Odometry nor a Position component");
    }
  }
  const std::string mode = mode_.get_string();
  mode_id_ = mode == "roll"  ? interfaces::kScan3dModeRoll
             : mode == "yaw" ? interfaces::kScan3dModeYaw
                             : interfaces::kScan3dModePitch;
  // The pipeline's options and the sweep's angles were checked (check_parameters, before init()).
  files_.clear();
  if (file_source_) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_directory(pcd, ec)) {
      for (const auto& e : fs::directory_iterator(pcd, ec)) {
        if (e.path().extension() == ".pcd") files_.push_back(e.path().string());
      }
      if (ec) throw std::runtime_error("pcd '" + pcd + "': " + ec.message());
      std::sort(files_.begin(), files_.end());
      if (files_.empty()) throw std::runtime_error("pcd '" + pcd + "': the directory has no *.pcd file");
    } else if (fs::exists(pcd, ec)) {
      files_.push_back(pcd);
    } else {
      throw std::runtime_error("pcd '" + pcd + "': no such file or directory");
    }
  }
  // Capacity of one sweep before processing: beams x scans; points past it are dropped (counted).
  assembler_ = std::make_unique<scan3d::Scan3dAssembler>(4 * interfaces::kScan3dMaxPoints * 4);
  pipeline_ = std::make_unique<scan3d::Scan3dPipeline>();
  out_ = std::make_unique<Scan3dData>();
  image_ = std::make_unique<interfaces::Scan3dRangeImage>();
  pending_ = std::make_unique<LadarData[]>(kPendingScans);
  if (file_source_) {
    log_info("%zu PCD file(s) from %s, one every %.0f ms", files_.size(), pcd, pcd_period_ms_.get_float());
  }
}

void Scan3d::describe_status(std::string& out) const {
  char line[160];
  std::snprintf(line, sizeof line, "scans %llu, last %u points in %.1f ms, bad input %llu, dropped 2-D scans %llu",
                static_cast<unsigned long long>(published_scans_.load(std::memory_order_relaxed)),
                last_points_.load(std::memory_order_relaxed),
                static_cast<double>(last_ms_.load(std::memory_order_relaxed)),
                static_cast<unsigned long long>(bad_input_.load(std::memory_order_relaxed)),
                static_cast<unsigned long long>(dropped_scans_.load(std::memory_order_relaxed)));
  out += line;
}

bool Scan3d::move_drive(double target) noexcept {
  interfaces::ServoDriveMovePos m;
  m.position = target;
  m.velocity = sweep_velocity_.get_float();
  alignas(8) std::byte buf[512];
  const auto r = data_endpoint().call(servo_.source(), interfaces::kServoDriveMovePos, m, std::span<std::byte>(buf),
                                      settings().rpc_timeout_ns);
  if (!r.ok()) {
    log_error("the drive %s refused MOVE_POS to %.3f rad (not homed, or outside its limits?)", servo_.source(), target);
    return false;
  }
  return true;
}

HookResult Scan3d::on() {  // the ladar, the drive and the odometry are on and subscribed already
  requests_.clear();       // requests left from before an OFF: their callers gave up
  pending_head_ = pending_count_ = 0;
  have_drive_ = false;
  phase_ = Phase::kToStart;
  sweep_from_ = angle_min_.get_float();
  sweep_to_ = angle_max_.get_float();
  sweep_end_ns_ = 0;
  newest_ladar_ns_ = 0;
  scan_number_ = 0;
  out_->bad_input = 0;
  next_file_ = 0;
  const int64_t now = rt::monotonic_ns();
  next_file_mono_ = now;
  last_ladar_mono_ = last_drive_mono_ = last_pose_mono_ = sweep_started_mono_ = now;
  if (file_source_) return HookResult::kOk;
  assembler_->reset();
  assembler_->clear_poses();  // after an ERROR or OFF: no interpolation across the gap
  scan3d::AssemblerConfig c;
  c.mount = Scan3dMount{mode_id_, mount_x_.get_float(), mount_y_.get_float(), mount_z_.get_float()};
  c.range_min = range_min_.get_float();
  c.range_max = range_max_.get_float();
  c.compensate_motion = compensate_;
  assembler_->set_config(c);
  // To the start of the first sweep.
  const tims::Address servo = servo_.source();
  interfaces::ServoDriveMovePos m;
  m.position = sweep_from_;
  m.velocity = sweep_velocity_.get_float();
  alignas(8) std::byte buf[512];
  const auto r = command_endpoint().call(servo, interfaces::kServoDriveMovePos, m, std::span<std::byte>(buf),
                                         settings().rpc_timeout_ns);
  if (!r.ok()) {
    log_error("the drive %s refused MOVE_POS to %.3f rad (not homed, or outside its limits?)", servo, sweep_from_);
    return HookResult::kError;  // the framework unsubscribes
  }
  return HookResult::kOk;
}

CommandResult Scan3d::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kScan3dGetRangeImage && request.type != interfaces::kScan3dStoreData) {
    return CommandResult::kUnknown;
  }
  // Only the data task serves these, and it runs only while ENABLED.
  if (state() != ComponentState::kEnabled) {
    reply_error(request, "Scan3D is not ENABLED (switch it on first)");
    return CommandResult::kHandled;
  }
  Request r;
  r.header = request;
  if (request.type == interfaces::kScan3dGetRangeImage) {
    if (!body.empty() && !wire::read_payload(body, tims::body_is_native(request), r.range)) {
      reject_malformed(request, "GET_RANGE_IMAGE: body must be empty or a Scan3dRangeImageRequest (8 bytes)");
      return CommandResult::kHandled;
    }
  } else if (!body.empty()) {
    if (!wire::read_payload(body, tims::body_is_native(request), r.store) ||
        std::memchr(r.store.path, '\0', sizeof r.store.path) == nullptr) {
      reject_malformed(request, "STORE_DATA: body must be empty or a Scan3dStoreData (240-byte NUL-terminated path)");
      return CommandResult::kHandled;
    }
  }
  bool busy = false;
  requests_.post([&](Requests& q) {
    if (q.count < kMaxRequests) {
      q.item[q.count++] = r;
    } else {
      busy = true;
    }
  });
  if (busy) {
    reply_error(request, "busy: 4 range-image/store requests are waiting");
    return CommandResult::kHandled;
  }
  wake_loop();  // the data task serves it after its current work
  return CommandResult::kHandled;
}

void Scan3d::reply_error_from_data(const tims::MessageHeader& request, const std::string& reason) noexcept {
  wire::ErrorText text;
  wire::copy_text(text.text, reason.c_str());
  const tims::ConstBuffer part = tims::buffer_of(text);
  (void)data_endpoint().reply(request, tims::msg::kError, std::span<const tims::ConstBuffer>(&part, 1));
}

void Scan3d::serve_requests() {
  Requests taken;
  if (!requests_.take(taken)) return;
  for (std::size_t i = 0; i < taken.count; ++i) {
    const Request& r = taken.item[i];
    if (!have_scan_) {
      reply_error_from_data(r.header, "no scan yet");
      continue;
    }
    if (r.header.type == interfaces::kScan3dGetRangeImage) {
      double res_deg = r.range.angular_resolution_deg > 0.0F ? static_cast<double>(r.range.angular_resolution_deg)
                                                             : range_image_res_deg_.get_float();
      std::string error;
      // The ladar's centre is the view point (files: the robot's origin at mount height).
      if (!scan3d::Scan3dPipeline::range_image(*out_, mount_x_.get_float(), mount_y_.get_float(), mount_z_.get_float(),
                                               res_deg * kDeg, *image_, error)) {
        reply_error_from_data(r.header, "range image: " + error);
        continue;
      }
      image_->scan_number = out_->scan_number;
      image_->scan_time_ns = scan_time_ns_;
      const tims::ConstBuffer part = tims::buffer_of(*image_);
      (void)data_endpoint().reply(r.header, interfaces::kScan3dRangeImageReply,
                                  std::span<const tims::ConstBuffer>(&part, 1));
    } else {
      // A relative path is the host file's folder's, as in the host file and SET_PARAM.
      std::string path = resolve_path(settings().base_dir, r.store.path);
      if (path.empty()) path = store_dir_.get_string() + "/scan3d_" + std::to_string(out_->scan_number) + ".pcd";
      std::string error;
      if (!scan3d::write_pcd(path, *out_, error)) {
        log_error("STORE_DATA: %s", error.c_str());
        reply_error_from_data(r.header, error);
        continue;
      }
      log_info("STORE_DATA: scan %u (%u points) written to %s", out_->scan_number, out_->point_count, path.c_str());
      (void)data_endpoint().reply(r.header, tims::msg::kOk);
    }
  }
}

void Scan3d::count_bad(BadKind kind, const char* detail) noexcept {
  static constexpr const char* kWhat[] = {"a PCD file", "a ladar scan", "a sweep", "a drive position",
                                          "an odometry pose"};
  static_assert(std::size(kWhat) == kBadKinds);
  const auto i = static_cast<std::size_t>(kind);
  out_->bad_input++;
  bad_input_.fetch_add(1, std::memory_order_relaxed);
  const uint64_t k = ++bad_kinds_[i];
  if (detail != nullptr && k % 100 == 1)
    log_warning("skipped %s: %s (%llu of this kind so far)", kWhat[i], detail, static_cast<unsigned long long>(k));
}

void Scan3d::finish_scan(int64_t time_ns, int64_t duration_ns, uint8_t mode, uint32_t ladar_scans, const float* x,
                         const float* y, const float* z, const float* intensity, std::size_t n) {
  Scan3dData& d = *out_;
  pipeline_->process(x, y, z, intensity, n, read_options(), d);
  d.mode = mode;
  d.duration_ns = duration_ns;
  d.ladar_scans = ladar_scans;
  d.scan_number = ++scan_number_;
  publish(d, time_ns);
  scan_time_ns_ = time_ns;
  have_scan_ = true;
  published_scans_.fetch_add(1, std::memory_order_relaxed);
  last_points_.store(d.point_count, std::memory_order_relaxed);
  last_ms_.store(d.process_ms, std::memory_order_relaxed);
  log_detail("scan %u: %u raw points -> %u (ground %u, objects %u, ceiling %u) in %.1f ms", d.scan_number, d.raw_points,
             d.point_count, d.ground_points, d.object_points, d.ceiling_points, static_cast<double>(d.process_ms));
}

HookResult Scan3d::loop() {
  const int64_t now = rt::monotonic_ns();
  HookResult result = HookResult::kOk;
  try {
    result = file_source_ ? loop_files(now) : loop_ladar(now);
    serve_requests();
  } catch (const std::exception& e) {
    log_error("processing failed: %s", e.what());
    return HookResult::kError;
  }
  return result;
}

HookResult Scan3d::loop_files(int64_t now) {
  (void)receive([](const InputPort&) {});  // no input is configured: only wake-ups arrive
  if (now < next_file_mono_) return HookResult::kOk;
  next_file_mono_ = std::max(next_file_mono_ + static_cast<int64_t>(pcd_period_ms_.get_float() * 1e6), now);
  if (next_file_ >= files_.size()) {
    if (!pcd_loop_.get_bool()) return HookResult::kOk;  // played once; the last scan stays
    next_file_ = 0;
  }
  const std::string& path = files_[next_file_++];
  scan3d::PcdCloud cloud;
  std::string error;
  if (!scan3d::read_pcd(path, cloud, error)) {
    count_bad(BadKind::kPcdFile, error.c_str());
    return HookResult::kOk;  // skipped: the next file may be fine
  }
  if (cloud.size() == 0) {
    count_bad(BadKind::kPcdFile, (path + ": no finite point").c_str());
    return HookResult::kOk;
  }
  finish_scan(rt::host_time_ns(), 0, interfaces::kScan3dModeFile, 0, cloud.x.data(), cloud.y.data(), cloud.z.data(),
              cloud.intensity.data(), cloud.size());
  return HookResult::kOk;
}

void Scan3d::count_malformed(const InputPort& in, uint64_t before, BadKind kind) noexcept {
  for (uint64_t n = in.malformed() - before; n > 0; --n) count_bad(kind, nullptr);
}

void Scan3d::take_pose(int64_t now) noexcept {
  components::Pose2d pose;
  if (odometry_.holds<PositionData>()) {
    const PositionData& p = odometry_.value<PositionData>();
    pose = components::Pose2d{p.x, p.y, p.phi};
  } else {
    const OdometryData& o = odometry_.value<OdometryData>();
    pose = components::Pose2d{o.x, o.y, o.phi};
  }
  if (!std::isfinite(pose.x) || !std::isfinite(pose.y) || !std::isfinite(pose.phi)) {
    count_bad(BadKind::kPose, "x, y or phi is not a finite number");
    return;
  }
  (void)assembler_->add_pose(odometry_.time_ns(), pose);  // an older or repeated pose is ignored
  last_pose_mono_ = now;
}

void Scan3d::take_drive(int64_t now) noexcept {
  const ServoDriveData& d = servo_.value();
  if (!std::isfinite(d.position)) {
    count_bad(BadKind::kDrive, "position is not a finite number");
    return;
  }
  assembler_->add_drive_sample(servo_.time_ns(), d.position);
  drive_ = d;
  drive_time_ns_ = servo_.time_ns();
  have_drive_ = true;
  last_drive_mono_ = now;
}

void Scan3d::take_scan(int64_t now) noexcept {
  const int64_t time_ns = ladar_.time_ns();
  last_ladar_mono_ = now;
  newest_ladar_ns_ = std::max(newest_ladar_ns_, time_ns);
  if (phase_ != Phase::kSweeping || time_ns < sweep_start_ns_) return;  // between sweeps
  if (pending_count_ == kPendingScans) {                                // the drive lags far behind: drop the oldest
    pending_head_ = (pending_head_ + 1) % kPendingScans;
    --pending_count_;
    dropped_scans_.fetch_add(1, std::memory_order_relaxed);
  }
  const std::size_t slot = (pending_head_ + pending_count_) % kPendingScans;
  pending_[slot] = ladar_.value();
  pending_time_[slot] = time_ns;
  ++pending_count_;
}

HookResult Scan3d::loop_ladar(int64_t now) {
  const tims::Address servo = servo_.source();
  const tims::Address ladar = ladar_.source();
  const tims::Address odometry = odometry_.source();  // 0 without compensation
  const uint64_t malformed_before[] = {ladar_.malformed(), servo_.malformed(), odometry_.malformed()};
  const Received r = receive([&](const InputPort& in) {
    if (&in == &odometry_) {
      take_pose(now);
    } else if (&in == &servo_) {
      take_drive(now);
    } else {
      take_scan(now);
    }
  });
  // A DATA message that did not decode (logged and counted as malformed by the input path).
  count_malformed(ladar_, malformed_before[0], BadKind::kLadarScan);
  count_malformed(servo_, malformed_before[1], BadKind::kDrive);
  count_malformed(odometry_, malformed_before[2], BadKind::kPose);
  if (r.failed) return HookResult::kError;  // a source left ENABLED (the error reason names it)
  const int64_t silence = silence_ns();
  if (now - last_ladar_mono_ > silence) {
    log_error("the ladar %s sent no scan for %lld ms", ladar, static_cast<long long>(silence / rt::kNsPerMs));
    return HookResult::kError;
  }
  if (now - last_drive_mono_ > silence) {
    log_error("the drive %s sent no position for %lld ms", servo, static_cast<long long>(silence / rt::kNsPerMs));
    return HookResult::kError;
  }
  if (compensate_ && now - last_pose_mono_ > silence) {
    log_error("the odometry %s sent no pose for %lld ms", odometry, static_cast<long long>(silence / rt::kNsPerMs));
    return HookResult::kError;
  }
  if (!have_drive_) return HookResult::kOk;
  const double tol = angle_tolerance_.get_float();
  const bool at_target = drive_.target_reached != 0 && std::fabs(drive_.target - sweep_to_) < tol &&
                         std::fabs(drive_.position - sweep_to_) < tol;
  if (phase_ == Phase::kSweeping && sweep_end_ns_ == 0 && at_target && drive_time_ns_ > sweep_start_ns_) {
    sweep_end_ns_ = drive_time_ns_;
  }
  // Place the waiting scans whose drive angles are known (up to the sweep's end: later
  // ones belong to the next sweep).
  while (pending_count_ > 0) {
    const std::size_t slot = pending_head_;
    if (sweep_end_ns_ != 0 && pending_time_[slot] > sweep_end_ns_) break;
    const scan3d::AddStatus s = assembler_->add_scan(pending_[slot], pending_time_[slot]);
    if (s == scan3d::AddStatus::kWaitForDrive) break;
    if (s == scan3d::AddStatus::kWaitForPose) {
      // Poses arrive, but none covers this scan: the odometry's clock or stream lags
      // (or its poses are not newer than the ones before).
      const int64_t lag = pending_time_[slot] - assembler_->pose_newest_time();
      if (assembler_->poses() > 0 && lag > silence) {
        log_error(
            "the odometry %s has no pose for the ladar scan at %lld ns: its newest pose is %lld ms older (silence_ms %lld)",
            odometry, static_cast<long long>(pending_time_[slot]), static_cast<long long>(lag / rt::kNsPerMs),
            static_cast<long long>(silence / rt::kNsPerMs));
        return HookResult::kError;
      }
      break;
    }
    if (s != scan3d::AddStatus::kAdded) count_bad(BadKind::kLadarScan, scan3d::describe(s));
    pending_head_ = (pending_head_ + 1) % kPendingScans;
    --pending_count_;
  }
  if (phase_ == Phase::kToStart) {
    const bool at_start = drive_.target_reached != 0 && std::fabs(drive_.position - sweep_from_) < tol;
    // With odometry, a sweep starts once there is a pose (its scans must be covered).
    if (at_start && (!compensate_ || assembler_->poses() > 0)) {
      phase_ = Phase::kSweeping;
      sweep_start_ns_ = compensate_ ? std::max(drive_time_ns_, assembler_->pose_oldest_time()) : drive_time_ns_;
      sweep_end_ns_ = 0;
      sweep_started_mono_ = now;
      assembler_->reset();
      if (!move_drive(sweep_to_)) return HookResult::kError;
    } else if (now - sweep_started_mono_ > static_cast<int64_t>(sweep_timeout_s_.get_float() * 1e9)) {
      log_error("the drive did not reach the sweep's start %.3f rad within %.1f s (at %.3f)", sweep_from_,
                sweep_timeout_s_.get_float(), drive_.position);
      return HookResult::kError;
    }
    return HookResult::kOk;
  }
  if (sweep_end_ns_ == 0) {
    if (now - sweep_started_mono_ > static_cast<int64_t>(sweep_timeout_s_.get_float() * 1e9)) {
      log_error("the drive did not finish a sweep to %.3f rad within %.1f s (at %.3f)", sweep_to_,
                sweep_timeout_s_.get_float(), drive_.position);
      return HookResult::kError;
    }
    return HookResult::kOk;
  }
  // The sweep is over once every scan that started before its end is placed: a scan
  // that started later has arrived, and none before the end is waiting.
  const bool waiting = pending_count_ > 0 && pending_time_[pending_head_] <= sweep_end_ns_;
  if (newest_ladar_ns_ < sweep_end_ns_ || waiting) return HookResult::kOk;
  // Turn the drive round first (the next sweep runs while this one is processed).
  const int64_t start_ns = assembler_->first_time_ns();
  const int64_t end_ns = assembler_->last_time_ns();
  const int64_t duration = end_ns - start_ns;
  // With odometry: the points into the robot frame at the sweep's end, stamped with it.
  const bool end_frame = compensate_ && assembler_->to_end_frame();
  const uint32_t scans = assembler_->scans();
  const uint32_t n = assembler_->size();
  if (assembler_->dropped_points() > 0) {
    log_warning("sweep had more than %u points: %u dropped", assembler_->capacity(), assembler_->dropped_points());
  }
  std::swap(sweep_from_, sweep_to_);
  sweep_start_ns_ = sweep_end_ns_;
  sweep_end_ns_ = 0;
  sweep_started_mono_ = rt::monotonic_ns();
  const bool moved = move_drive(sweep_to_);
  // The new sweep's scans stay in the mailbox until the next loop(): the assembler's
  // points are this sweep's until finish_scan() has copied them.
  if (n > 0) {
    finish_scan(end_frame ? end_ns : start_ns, duration, mode_id_, scans, assembler_->x(), assembler_->y(),
                assembler_->z(), assembler_->intensity(), n);
  } else {
    count_bad(BadKind::kSweep, "no ladar point in a whole sweep");
  }
  assembler_->reset();
  if (!moved) return HookResult::kError;
  // Scans that started before the new sweep's start belong to no sweep.
  while (pending_count_ > 0 && pending_time_[pending_head_] < sweep_start_ns_) {
    pending_head_ = (pending_head_ + 1) % kPendingScans;
    --pending_count_;
  }
  return HookResult::kOk;
}

}  // namespace rack::components
