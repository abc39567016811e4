#include "path/path.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

namespace rack::components {

using interfaces::PathData;
using interfaces::PathMake;

Path::Path()
    : DataComponent(DataTaskMode::kPeriodic),
      waypoints_(declare_string(
          "waypoints", "", {.doc = "\"x,y; x,y; ...\" in metres, map frame (2..32 points; empty: none until MAKE)"})),
      closed_(declare_bool("closed", false, {.doc = "join the last waypoint to the first (a loop)"})),
      resolution_(
          declare_float("resolution", 0.1, {.doc = "m between sampled path points", .min = 0.01, .max = 10.0})) {
  set_command_slot_size(sizeof(tims::MessageHeader) + sizeof(PathMake) + 64);
}

const char* Path::parse_waypoints(const char* text, PathMake& out, int& item) noexcept {
  out.count = 0;
  item = 0;
  const char* p = text;
  const auto skip_space = [&p] {
    while (*p == ' ' || *p == '\t') ++p;
  };
  skip_space();
  if (*p == '\0') return "no waypoints";
  for (;;) {
    item = static_cast<int>(out.count) + 1;
    if (out.count >= interfaces::kPathMaxWaypoints) return "more than 32 waypoints";
    char* end = nullptr;
    const double x = std::strtod(p, &end);
    if (end == p) return "expected a number for x";
    p = end;
    skip_space();
    if (*p != ',') return "expected ',' between x and y";
    ++p;
    const double y = std::strtod(p, &end);
    if (end == p) return "expected a number for y";
    p = end;
    if (!std::isfinite(x) || !std::isfinite(y)) return "coordinates must be finite";
    out.x[out.count] = x;
    out.y[out.count] = y;
    ++out.count;
    skip_space();
    if (*p == '\0') break;
    if (*p != ';') return "expected ';' between waypoints";
    ++p;
    skip_space();
    if (*p == '\0') break;  // a trailing ';' is fine
  }
  item = 0;
  return nullptr;
}

namespace {
struct Pt {
  double x, y;
};
Pt lerp(const Pt& a, const Pt& b, double t0, double t1, double t) noexcept {
  const double d = t1 - t0;
  if (d <= 0.0) return a;
  const double u = (t - t0) / d;
  return Pt{a.x + (b.x - a.x) * u, a.y + (b.y - a.y) * u};
}
double knot(const Pt& a, const Pt& b) noexcept {
  // Centripetal parametrisation (alpha = 0.5): Yuksel, Schaefer, Keyser, "On the
  // parameterization of Catmull-Rom curves" (2009): no cusps or self-intersections.
  return std::sqrt(std::hypot(b.x - a.x, b.y - a.y));
}
// A point of the segment p1->p2 (Barry and Goldman's pyramidal evaluation), u in [0, 1].
Pt catmull_rom(const Pt& p0, const Pt& p1, const Pt& p2, const Pt& p3, double u) noexcept {
  const double t0 = 0.0;
  const double t1 = t0 + std::max(knot(p0, p1), 1e-6);
  const double t2 = t1 + std::max(knot(p1, p2), 1e-6);
  const double t3 = t2 + std::max(knot(p2, p3), 1e-6);
  const double t = t1 + (t2 - t1) * u;
  const Pt a1 = lerp(p0, p1, t0, t1, t);
  const Pt a2 = lerp(p1, p2, t1, t2, t);
  const Pt a3 = lerp(p2, p3, t2, t3, t);
  const Pt b1 = lerp(a1, a2, t0, t2, t);
  const Pt b2 = lerp(a2, a3, t1, t3, t);
  return lerp(b1, b2, t1, t2, t);
}
}  // namespace

const char* Path::make_path(const PathMake& w, double resolution, PathData& out) noexcept {
  constexpr double kMaxCoordinate = 1e6;  // m: floats keep 6 cm steps there
  const uint32_t n = w.count;
  if (n < 2) return "a path needs at least 2 waypoints";
  if (n > interfaces::kPathMaxWaypoints) return "more than 32 waypoints";
  if (!(resolution > 0.0)) return "resolution must be > 0";
  const bool closed = w.closed != 0 && n >= 3;
  for (uint32_t i = 0; i < n; ++i) {
    if (!std::isfinite(w.x[i]) || !std::isfinite(w.y[i])) return "waypoints must be finite";
    // The sample carries floats: a finite double past FLT_MAX (y = 4e175 from a MAKE
    // body, found by tests/fuzz/fuzz_path.cpp) was published as inf.
    if (std::fabs(w.x[i]) > kMaxCoordinate || std::fabs(w.y[i]) > kMaxCoordinate) {
      return "waypoints must lie within 1000 km of the map origin";
    }
    const uint32_t j = i + 1 < n ? i + 1 : 0;
    if ((i + 1 < n || closed) && std::hypot(w.x[j] - w.x[i], w.y[j] - w.y[i]) < 1e-3) {
      return "two consecutive waypoints are equal";
    }
  }
  const auto at = [&](int64_t i) -> Pt {
    const auto nn = static_cast<int64_t>(n);
    if (closed) return Pt{w.x[((i % nn) + nn) % nn], w.y[((i % nn) + nn) % nn]};
    // Open ends: mirror the neighbour so the end tangent follows the first/last leg.
    if (i < 0) return Pt{2.0 * w.x[0] - w.x[1], 2.0 * w.y[0] - w.y[1]};
    if (i >= nn) return Pt{2.0 * w.x[n - 1] - w.x[n - 2], 2.0 * w.y[n - 1] - w.y[n - 2]};
    return Pt{w.x[i], w.y[i]};
  };
  out.waypoint_count = n;
  for (uint32_t i = 0; i < n; ++i) {
    out.waypoint_x[i] = static_cast<float>(w.x[i]);
    out.waypoint_y[i] = static_cast<float>(w.y[i]);
  }
  out.closed = closed ? 1 : 0;
  const uint32_t segments = closed ? n : n - 1;
  uint32_t k = 0;
  double length = 0.0;
  Pt prev = at(0);
  for (uint32_t s = 0; s < segments; ++s) {
    const auto i = static_cast<int64_t>(s);
    const Pt p0 = at(i - 1), p1 = at(i), p2 = at(i + 1), p3 = at(i + 2);
    const double chord = std::hypot(p2.x - p1.x, p2.y - p1.y);
    // Checked as a double before it is narrowed: a chord of 1e35 m (or inf) is too long,
    // not a wrapped step count (found by tests/fuzz/fuzz_host_config.cpp).
    const double want = std::ceil(chord / resolution);
    if (!(want <= static_cast<double>(interfaces::kPathMaxPoints))) {
      return "path too long for 2048 points: raise 'resolution'";
    }
    const auto steps = static_cast<uint32_t>(std::max(1.0, want));
    for (uint32_t j = 0; j < steps; ++j) {
      if (k >= interfaces::kPathMaxPoints) return "path too long for 2048 points: raise 'resolution'";
      const Pt p = catmull_rom(p0, p1, p2, p3, static_cast<double>(j) / static_cast<double>(steps));
      if (k > 0) length += std::hypot(p.x - prev.x, p.y - prev.y);
      out.x[k] = static_cast<float>(p.x);
      out.y[k] = static_cast<float>(p.y);
      prev = p;
      ++k;
    }
  }
  const Pt last = closed ? at(0) : at(n - 1);
  if (k >= interfaces::kPathMaxPoints) return "path too long for 2048 points: raise 'resolution'";
  length += std::hypot(last.x - prev.x, last.y - prev.y);
  if (!closed) {
    out.x[k] = static_cast<float>(last.x);
    out.y[k] = static_cast<float>(last.y);
    ++k;
  }
  out.point_count = k;
  out.length = length;
  // Clear what a previous, longer path left behind (tools print whole arrays).
  for (uint32_t i = n; i < interfaces::kPathMaxWaypoints; ++i) out.waypoint_x[i] = out.waypoint_y[i] = 0.0F;
  for (uint32_t i = k; i < interfaces::kPathMaxPoints; ++i) out.x[i] = out.y[i] = 0.0F;
  return nullptr;
}

bool Path::make_from_parameters(PathData& out, char (&error)[96]) noexcept {
  char text[wire::kParamStringLen];
  waypoints_.copy_string(text, sizeof text);
  PathMake w;
  int item = 0;
  const char* why = parse_waypoints(text, w, item);
  if (why == nullptr) {
    w.closed = closed_.get_bool() ? 1 : 0;
    why = make_path(w, resolution_.get_float(), out);
  }
  if (why == nullptr) return true;
  wire::copy_text(error, "waypoints");
  if (item > 0) {
    // Two digits at most (32 waypoints); no printf in RT code.
    char num[] = " item 00";
    num[6] = static_cast<char>('0' + (item / 10) % 10);
    num[7] = static_cast<char>('0' + item % 10);
    wire::append_text(error, item < 10 ? " item " : "");
    wire::append_text(error, item < 10 ? num + 7 : num);
  }
  wire::append_text(error, ": ");
  wire::append_text(error, why);
  return false;
}

void Path::init() {
  // The waypoint text was checked (check_parameters, before init()).
  char error[96] = {};
  (void)make_from_parameters(current_, error);
}

bool Path::check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept {
  // The same parse and spline as the data task's (make_from_parameters), on the
  // values to check: a text the loop would reject is refused where it is set.
  char text[wire::kParamStringLen];
  values.copy_string(waypoints_, text, sizeof text);
  if (text[0] == '\0') return true;  // no path until MAKE
  PathMake w;
  int item = 0;
  const char* why = parse_waypoints(text, w, item);
  if (why == nullptr) {
    w.closed = values.get_bool(closed_) ? 1 : 0;
    why = make_path(w, values.get_float(resolution_), check_);
    item = 0;
  }
  if (why == nullptr) return true;
  char reason[sizeof problem.text] = {};
  if (item > 0) {
    char num[] = "item 00: ";
    num[5] = static_cast<char>('0' + (item / 10) % 10);
    num[6] = static_cast<char>('0' + item % 10);
    wire::append_text(reason, item < 10 ? "item " : "");
    wire::append_text(reason, item < 10 ? num + 6 : num);
  }
  wire::append_text(reason, why);
  problem.set(waypoints_, reason);
  return false;
}

HookResult Path::on() {
  makes_ = 0;
  rejected_ = 0;
  last_error_[0] = '\0';
  make_rejected_.store(0, std::memory_order_relaxed);
  last_text_[0] = '\x01';  // differs from any parameter text: the loop makes the path at once
  last_closed_ = closed_.get_bool();
  made_.clear();
  return HookResult::kOk;
}

HookResult Path::loop() {
  bool publish_now = false;
  if (made_.take(current_)) {
    publish_now = true;
    ++makes_;
  }
  char text[wire::kParamStringLen];
  waypoints_.copy_string(text, sizeof text);
  const bool closed = closed_.get_bool();
  const double resolution = resolution_.get_float();
  if (std::strcmp(text, last_text_) != 0 || closed != last_closed_ || resolution != last_resolution_) {
    std::memcpy(last_text_, text, sizeof text);
    last_closed_ = closed;
    last_resolution_ = resolution;
    if (text[0] != '\0') {
      if (make_from_parameters(current_, last_error_)) {
        ++makes_;
        publish_now = true;
      } else {
        ++rejected_;
        publish_now = true;  // tell listeners about the rejection; the previous path stays
      }
    }
  }
  if (publish_now) {
    current_.makes = makes_;
    current_.rejected = rejected_ + make_rejected_.load(std::memory_order_relaxed);
    std::memcpy(current_.last_error, last_error_, sizeof last_error_);
    publish(current_, rt::host_time_ns());
  }
  return HookResult::kOk;
}

CommandResult Path::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  if (request.type != interfaces::kPathMake) return CommandResult::kUnknown;
  const char* why = nullptr;
  char error[96] = {};
  if (body.empty()) {
    if (!make_from_parameters(scratch_, error)) why = error;
  } else {
    PathMake w;
    if (!wire::read_payload(body, tims::body_is_native(request), w)) {
      reject_malformed(request, "MAKE: body must be empty or a PathMake");
      return CommandResult::kHandled;
    }
    why = make_path(w, resolution_.get_float(), scratch_);
  }
  if (why != nullptr) {
    make_rejected_.fetch_add(1, std::memory_order_relaxed);
    wire::ErrorText text;
    wire::copy_text(text.text, "MAKE: ");
    wire::append_text(text.text, why);
    reply_with(request, tims::msg::kError, text);
    return CommandResult::kHandled;
  }
  made_.post(scratch_);
  reply(request, tims::msg::kOk);  // published by the data task within one period
  return CommandResult::kHandled;
}

}  // namespace rack::components
