// GridPlanner: the way from the robot to a destination on an occupancy grid map, as
// up to 32 waypoints for Path::make_path's spline (the Pilot plans with it).
//
// The robot is a disc of `radius` metres (the pilot uses the circle round the chassis'
// outline plus a margin): set_map() computes each cell's exact Euclidean distance to
// the nearest cell that is not free (Felzenszwalb and Huttenlocher, "Distance
// Transforms of Sampled Functions", Theory of Computing 8, 2012), so inflating by any
// radius is one comparison per cell and costs nothing at plan time. Unknown cells and
// everything outside the grid count as walls.
//
// plan() is A* (Hart, Nilsson, Raphael 1968) over the 8-connected cells the disc fits
// in, with the octile heuristic; a step near a wall costs more (up to 1 + kComfortWeight
// times, within `comfort` metres beyond the radius), so the way keeps to the middle of
// corridors and doors where it can. The cell path is then shortened to waypoints by
// line of sight ("string pulling"): a straight leg is taken only where it keeps at
// least the clearance the A* path had there (or radius + comfort), so the spline
// through the waypoints does not cut the corners the cost kept it from.
//
// Temporary obstacles (points the robot's scanner sees that the map lacks, e.g. when
// the pilot is blocked) are stamped as discs of `radius` into an overlay with
// add_obstacle() and cleared with clear_obstacles().
//
// Real-time contract: set_map() is set-up (allocates every buffer, O(cells)); all
// other members allocate nothing, lock nothing and make no system call. plan() runs
// for O(cells log cells) in the worst case (a few ms on the 24 m x 16 m office map at
// 5 cm): call it where a long computation does not delay a control loop (the Pilot
// runs it in its command task). Not thread-safe: one thread plans at a time.
#pragma once

#include <cstdint>
#include <vector>

#include "rack/interfaces/navigation.h"
#include "rack/maps/occupancy_map.h"

namespace rack::components {

class GridPlanner {
 public:
  // The largest grid planned on (width x height): 4 Mi cells, about 90 MB of buffers.
  static constexpr uint64_t kMaxCells = uint64_t{1} << 22;
  // A step with no clearance beyond the radius costs 1 + kComfortWeight times its length.
  static constexpr double kComfortWeight = 3.0;

  struct Options {
    double radius = 0.4;   // m, the robot as a disc: no cell closer to a wall than this
    double comfort = 0.4;  // m beyond the radius within which steps cost more
  };
  struct Result {
    const char* error = nullptr;  // nullptr: planned; else why not (a static text)
    uint32_t expanded = 0;        // cells A* expanded
    double length = 0.0;          // m, along the waypoints
    bool start_moved = false;     // the robot stood closer to a wall than the radius: the
                                  // way starts at the nearest cell with room (within 1 m)
  };

  // Not RT: keeps the grid, computes the distance field, allocates the search buffers.
  // Throws std::runtime_error for a map with more than kMaxCells cells.
  void set_map(const maps::OccupancyMap& map);
  [[nodiscard]] bool has_map() const noexcept { return width_ > 0; }

  // Metres from (x, y) to the nearest wall or unknown cell (0 in one or outside the map),
  // ignoring temporary obstacles. RT-safe.
  [[nodiscard]] double clearance(double x, double y) const noexcept;

  // Temporary obstacles (RT-safe). add_obstacle marks every cell within `radius` of
  // (x, y) (map frame) as blocked; points outside the map are ignored.
  void clear_obstacles() noexcept;
  void add_obstacle(double x, double y, double radius) noexcept;

  // Plans from (sx, sy) to (gx, gy) (map frame). On success `out` holds the waypoints
  // (the start, the turns, the destination; out.closed = 0). RT-safe (no allocation),
  // bounded by the grid's size.
  Result plan(double sx, double sy, double gx, double gy, const Options& options, interfaces::PathMake& out) noexcept;

 private:
  [[nodiscard]] bool passable(uint32_t cell) const noexcept;
  [[nodiscard]] double cell_clearance(uint32_t cell) const noexcept;  // m, beyond nothing
  [[nodiscard]] bool line_clear(uint32_t a, uint32_t b, double need) const noexcept;
  [[nodiscard]] bool nearest_passable(int ix, int iy, double max_m, uint32_t& out) const noexcept;
  void heap_push(uint32_t cell) noexcept;
  void heap_update(uint32_t cell) noexcept;  // its f fell
  uint32_t heap_pop() noexcept;
  void sift_up(uint32_t i) noexcept;
  void sift_down(uint32_t i) noexcept;

  maps::OccupancyMap map_;
  int width_ = 0, height_ = 0;
  double resolution_ = 0.0;
  double radius_cells2_ = 0.0;     // (radius / resolution)^2 of the running plan
  std::vector<float> dist2_;       // squared distance in cells to the nearest non-free cell
  std::vector<uint8_t> blocked_;   // temporary obstacles
  std::vector<float> g_, f_;       // A* costs (cells)
  std::vector<int32_t> parent_;    // -1: none
  std::vector<int32_t> heap_pos_;  // -1 never seen, -2 closed, else index in heap_
  std::vector<uint32_t> heap_;
  uint32_t heap_size_ = 0;
  std::vector<uint32_t> trace_;  // the cell path, start first
};

}  // namespace rack::components
