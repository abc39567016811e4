#include "path/planner.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace rack::components {

namespace {
constexpr double kFar = 1e20;  // "no wall" in the squared-distance transform (finite: no inf - inf)

// One dimension of the squared Euclidean distance transform (Felzenszwalb and
// Huttenlocher 2012, section 3): d[q] = min over p of (q - p)^2 + f[p], through the
// lower envelope of the parabolas rooted at each p. v, z: scratch of n and n + 1.
void distance_1d(const double* f, int n, double* d, int* v, double* z) {
  int k = 0;
  v[0] = 0;
  z[0] = -kFar;
  z[1] = kFar;
  for (int q = 1; q < n; ++q) {
    const auto s_of = [&](int p) { return ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * q - 2.0 * p); };
    double s = s_of(v[k]);
    while (k > 0 && s <= z[k]) {
      --k;
      s = s_of(v[k]);
    }
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = kFar;
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < q) ++k;
    const double dq = q - v[k];
    d[q] = dq * dq + f[v[k]];
  }
}
}  // namespace

void GridPlanner::set_map(const maps::OccupancyMap& map) {
  const uint64_t cells = uint64_t(std::max(map.width(), 0)) * uint64_t(std::max(map.height(), 0));
  if (cells == 0) throw std::runtime_error("the map has no cells");
  if (cells > kMaxCells) {
    throw std::runtime_error("the map has " + std::to_string(cells) + " cells, more than the planner's " +
                             std::to_string(kMaxCells) + ": give the pilot a coarser map");
  }
  map_ = map;
  width_ = map.width();
  height_ = map.height();
  resolution_ = map.resolution();
  const auto n = static_cast<std::size_t>(cells);
  dist2_.assign(n, 0.0F);
  blocked_.assign(n, 0);
  g_.assign(n, 0.0F);
  f_.assign(n, 0.0F);
  parent_.assign(n, -1);
  heap_pos_.assign(n, -1);
  heap_.assign(n, 0);
  trace_.assign(n, 0);

  // Columns, then rows: the exact squared distance (in cells) to the nearest non-free cell.
  const int side = std::max(width_, height_);
  std::vector<double> f(static_cast<std::size_t>(side)), d(static_cast<std::size_t>(side)),
      z(static_cast<std::size_t>(side) + 1);
  std::vector<int> v(static_cast<std::size_t>(side));
  std::vector<double> columns(n);
  for (int ix = 0; ix < width_; ++ix) {
    for (int iy = 0; iy < height_; ++iy)
      f[std::size_t(iy)] = map.cell_state(ix, iy) == maps::CellState::kFree ? kFar : 0.0;
    distance_1d(f.data(), height_, d.data(), v.data(), z.data());
    for (int iy = 0; iy < height_; ++iy)
      columns[std::size_t(iy) * std::size_t(width_) + std::size_t(ix)] = d[std::size_t(iy)];
  }
  for (int iy = 0; iy < height_; ++iy) {
    const std::size_t row = std::size_t(iy) * std::size_t(width_);
    distance_1d(columns.data() + row, width_, d.data(), v.data(), z.data());
    for (int ix = 0; ix < width_; ++ix) {
      // Beyond the grid is a wall too: the cell one past each edge.
      const double edge = std::min({double(ix + 1), double(width_ - ix), double(iy + 1), double(height_ - iy)});
      dist2_[row + std::size_t(ix)] = static_cast<float>(std::min(d[std::size_t(ix)], edge * edge));
    }
  }
}

double GridPlanner::clearance(double x, double y) const noexcept {
  int ix = 0, iy = 0;
  if (!has_map() || !map_.world_to_cell(x, y, ix, iy)) return 0.0;
  return cell_clearance(uint32_t(iy) * uint32_t(width_) + uint32_t(ix)) * resolution_;
}

double GridPlanner::cell_clearance(uint32_t cell) const noexcept { return std::sqrt(double(dist2_[cell])); }

bool GridPlanner::passable(uint32_t cell) const noexcept {
  return double(dist2_[cell]) > radius_cells2_ && blocked_[cell] == 0;
}

void GridPlanner::clear_obstacles() noexcept {
  if (!blocked_.empty()) std::memset(blocked_.data(), 0, blocked_.size());
}

void GridPlanner::add_obstacle(double x, double y, double radius) noexcept {
  if (!has_map() || !std::isfinite(x) || !std::isfinite(y) || !(radius >= 0.0)) return;
  int cx = 0, cy = 0;
  if (!map_.world_to_cell(x, y, cx, cy)) return;
  const int r = static_cast<int>(std::ceil(std::min(radius, 50.0) / resolution_));
  const double r2 = (radius / resolution_) * (radius / resolution_);
  for (int dy = -r; dy <= r; ++dy) {
    const int iy = cy + dy;
    if (iy < 0 || iy >= height_) continue;
    for (int dx = -r; dx <= r; ++dx) {
      const int ix = cx + dx;
      if (ix < 0 || ix >= width_ || double(dx) * dx + double(dy) * dy > r2) continue;
      blocked_[std::size_t(iy) * std::size_t(width_) + std::size_t(ix)] = 1;
    }
  }
}

bool GridPlanner::nearest_passable(int cx, int cy, double max_m, uint32_t& out) const noexcept {
  const int r = static_cast<int>(std::ceil(max_m / resolution_));
  double best = std::numeric_limits<double>::infinity();
  for (int dy = -r; dy <= r; ++dy) {
    const int iy = cy + dy;
    if (iy < 0 || iy >= height_) continue;
    for (int dx = -r; dx <= r; ++dx) {
      const int ix = cx + dx;
      const double d2 = double(dx) * dx + double(dy) * dy;
      if (ix < 0 || ix >= width_ || d2 >= best || d2 > double(r) * r) continue;
      const uint32_t c = uint32_t(iy) * uint32_t(width_) + uint32_t(ix);
      if (passable(c)) {
        best = d2;
        out = c;
      }
    }
  }
  return std::isfinite(best);
}

bool GridPlanner::line_clear(uint32_t a, uint32_t b, double need) const noexcept {
  const double ax = a % uint32_t(width_) + 0.5, ay = a / uint32_t(width_) + 0.5;
  const double bx = b % uint32_t(width_) + 0.5, by = b / uint32_t(width_) + 0.5;
  const double len = std::hypot(bx - ax, by - ay);
  const auto steps = static_cast<int>(std::ceil(len * 2.0));  // every half cell
  for (int s = 0; s <= steps; ++s) {
    const double t = steps > 0 ? double(s) / steps : 0.0;
    const auto ix = static_cast<int>(ax + (bx - ax) * t);
    const auto iy = static_cast<int>(ay + (by - ay) * t);
    if (ix < 0 || iy < 0 || ix >= width_ || iy >= height_) return false;
    const uint32_t c = uint32_t(iy) * uint32_t(width_) + uint32_t(ix);
    if (!passable(c) || cell_clearance(c) < need) return false;
  }
  return true;
}

// The open list: a binary heap of cells on f_, heap_pos_ holding each cell's index.
void GridPlanner::sift_up(uint32_t i) noexcept {
  const uint32_t cell = heap_[i];
  while (i > 0) {
    const uint32_t up = (i - 1) / 2;
    if (f_[heap_[up]] <= f_[cell]) break;
    heap_[i] = heap_[up];
    heap_pos_[heap_[i]] = int32_t(i);
    i = up;
  }
  heap_[i] = cell;
  heap_pos_[cell] = int32_t(i);
}

void GridPlanner::sift_down(uint32_t i) noexcept {
  const uint32_t cell = heap_[i];
  for (;;) {
    uint32_t child = 2 * i + 1;
    if (child >= heap_size_) break;
    if (child + 1 < heap_size_ && f_[heap_[child + 1]] < f_[heap_[child]]) ++child;
    if (f_[cell] <= f_[heap_[child]]) break;
    heap_[i] = heap_[child];
    heap_pos_[heap_[i]] = int32_t(i);
    i = child;
  }
  heap_[i] = cell;
  heap_pos_[cell] = int32_t(i);
}

void GridPlanner::heap_push(uint32_t cell) noexcept {
  heap_[heap_size_] = cell;
  sift_up(heap_size_++);
}

void GridPlanner::heap_update(uint32_t cell) noexcept { sift_up(uint32_t(heap_pos_[cell])); }

uint32_t GridPlanner::heap_pop() noexcept {
  const uint32_t top = heap_[0];
  heap_pos_[top] = -2;
  if (--heap_size_ > 0) {
    heap_[0] = heap_[heap_size_];
    sift_down(0);
  }
  return top;
}

GridPlanner::Result GridPlanner::plan(double sx, double sy, double gx, double gy, const Options& options,
                                      interfaces::PathMake& out) noexcept {
  Result result;
  out.count = 0;
  out.closed = 0;
  if (!has_map()) return result.error = "no map to plan on", result;
  if (!std::isfinite(sx) || !std::isfinite(sy) || !std::isfinite(gx) || !std::isfinite(gy)) {
    return result.error = "the start or the destination is not a finite number", result;
  }
  if (!(options.radius >= 0.0) || !(options.comfort >= 0.0))
    return result.error = "radius and comfort must be >= 0", result;
  const double rc = options.radius / resolution_;
  radius_cells2_ = rc * rc;
  const double comfort_c = std::max(options.comfort / resolution_, 1e-9);

  int gix = 0, giy = 0, six = 0, siy = 0;
  if (!map_.world_to_cell(gx, gy, gix, giy)) return result.error = "the destination is outside the map", result;
  const uint32_t goal = uint32_t(giy) * uint32_t(width_) + uint32_t(gix);
  if (dist2_[goal] <= 0.0F) return result.error = "the destination is in a wall or an unknown part of the map", result;
  if (!passable(goal)) {
    return result.error = blocked_[goal] != 0 ? "the destination is blocked by an obstacle the scanner sees"
                                              : "the destination is closer to a wall than the robot's radius",
           result;
  }
  if (!map_.world_to_cell(sx, sy, six, siy)) return result.error = "the robot is outside the map", result;
  uint32_t start = uint32_t(siy) * uint32_t(width_) + uint32_t(six);
  if (!passable(start)) {
    if (!nearest_passable(six, siy, 1.0, start)) {
      return result.error = "the robot stands where it does not fit: no free cell within 1 m", result;
    }
    result.start_moved = true;
  }

  // A*.
  std::fill(heap_pos_.begin(), heap_pos_.end(), -1);
  heap_size_ = 0;
  const auto h = [&](uint32_t c) {
    const double dx = std::abs(double(int(c % uint32_t(width_)) - gix));
    const double dy = std::abs(double(int(c / uint32_t(width_)) - giy));
    return (std::max(dx, dy) - std::min(dx, dy)) + std::numbers::sqrt2 * std::min(dx, dy);
  };
  g_[start] = 0.0F;
  f_[start] = static_cast<float>(h(start));
  parent_[start] = -1;
  heap_push(start);
  static constexpr int kDx[8] = {1, -1, 0, 0, 1, 1, -1, -1};
  static constexpr int kDy[8] = {0, 0, 1, -1, 1, -1, 1, -1};
  bool found = false;
  while (heap_size_ > 0) {
    const uint32_t c = heap_pop();
    ++result.expanded;
    if (c == goal) {
      found = true;
      break;
    }
    const int cx = int(c % uint32_t(width_)), cy = int(c / uint32_t(width_));
    for (int k = 0; k < 8; ++k) {
      const int nx = cx + kDx[k], ny = cy + kDy[k];
      if (nx < 0 || ny < 0 || nx >= width_ || ny >= height_) continue;
      const uint32_t nc = uint32_t(ny) * uint32_t(width_) + uint32_t(nx);
      if (heap_pos_[nc] == -2 || !passable(nc)) continue;
      // Diagonal steps only where both side cells are passable (no corner cutting).
      if (k >= 4 && (!passable(uint32_t(cy) * uint32_t(width_) + uint32_t(nx)) ||
                     !passable(uint32_t(ny) * uint32_t(width_) + uint32_t(cx)))) {
        continue;
      }
      const double room = cell_clearance(nc) - rc;  // cells beyond the radius
      const double penalty = std::clamp((comfort_c - room) / comfort_c, 0.0, 1.0);
      const double step = (k >= 4 ? std::numbers::sqrt2 : 1.0) * (1.0 + kComfortWeight * penalty);
      const auto g = static_cast<float>(double(g_[c]) + step);
      if (heap_pos_[nc] >= 0 && g >= g_[nc]) continue;
      g_[nc] = g;
      f_[nc] = static_cast<float>(double(g) + h(nc));
      parent_[nc] = int32_t(c);
      if (heap_pos_[nc] >= 0) heap_update(nc);
      else heap_push(nc);
    }
  }
  if (!found) {
    return result.error =
               "no way there: the destination is cut off from the robot (walls, or obstacles the scanner sees)",
           result;
  }

  // The cell path, start first.
  uint32_t n = 0;
  for (int32_t c = int32_t(goal); c >= 0 && n < trace_.size(); c = parent_[uint32_t(c)]) trace_[n++] = uint32_t(c);
  std::reverse(trace_.begin(), trace_.begin() + n);

  // Waypoints: line of sight, never with less room than the A* path had (see header).
  double px[interfaces::kPathMaxWaypoints + 2], py[interfaces::kPathMaxWaypoints + 2];
  uint32_t count = 0;
  bool too_many = false;
  const auto emit = [&](double x, double y) {
    if (count >= interfaces::kPathMaxWaypoints) {
      too_many = true;
      return;
    }
    px[count] = x;
    py[count] = y;
    ++count;
  };
  emit(sx, sy);
  if (result.start_moved) {
    double x = 0.0, y = 0.0;
    map_.cell_to_world(int(start % uint32_t(width_)), int(start / uint32_t(width_)), x, y);
    emit(x, y);
  }
  const double want = rc + comfort_c;
  uint32_t anchor = 0;
  double segmin = cell_clearance(trace_[0]);
  for (uint32_t j = 1; j < n; ++j) {
    const double with_j = std::min(segmin, cell_clearance(trace_[j]));
    if (j == anchor + 1 || line_clear(trace_[anchor], trace_[j], std::min(with_j, want) - 0.5)) {
      segmin = with_j;
      continue;
    }
    anchor = j - 1;
    double x = 0.0, y = 0.0;
    map_.cell_to_world(int(trace_[anchor] % uint32_t(width_)), int(trace_[anchor] / uint32_t(width_)), x, y);
    emit(x, y);
    segmin = std::min(cell_clearance(trace_[anchor]), cell_clearance(trace_[j]));
  }
  if (std::hypot(gx - px[count - 1], gy - py[count - 1]) < 1e-3) {
    if (count == 1) return result.error = "the robot is at the destination", result;
    px[count - 1] = gx;  // the last turn is the destination's cell: end there
    py[count - 1] = gy;
  } else {
    emit(gx, gy);
  }
  if (too_many) return result.error = "the way needs more than 32 waypoints (a maze): give nearer destinations", result;
  out.count = count;
  for (uint32_t i = 0; i < count; ++i) {
    out.x[i] = px[i];
    out.y[i] = py[i];
    if (i > 0) result.length += std::hypot(px[i] - px[i - 1], py[i] - py[i - 1]);
  }
  return result;
}

}  // namespace rack::components
