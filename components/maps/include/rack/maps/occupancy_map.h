// Occupancy grid maps in the ROS map_server format: a YAML file naming a PGM image,
// its resolution and the pose of its lower-left pixel. Used by the simulators
// (LadarSim ray-casts it) and by localisation (MCL converts it to MRPT's grid).
//
//   image: office.pgm          # relative to the YAML file's folder, or absolute
//   resolution: 0.05           # metres per pixel
//   origin: [-1.0, -1.0, 0.0]  # x, y, yaw of the lower-left pixel in the map frame
//   negate: 0                  # 0: white is free, black occupied; 1: the reverse
//   occupied_thresh: 0.65      # occupancy probability above which a cell is occupied
//   free_thresh: 0.196         # ... below which it is free; between: unknown
//   mode: trinary              # optional: trinary (default), scale or raw
//
// A pixel's occupancy probability is p = (maxval - v) / maxval (negate: v / maxval),
// as map_server computes it. Cell (ix, iy) has its lower-left corner at origin +
// (ix, iy) * resolution in the map's own axes: iy = 0 is the image's BOTTOM row.
//
// Loading validates everything: missing or unknown keys, wrong types, thresholds out
// of order, an image that is missing, not PGM, truncated or of the wrong size; each
// error names the file and the YAML line or the image's byte offset.
//
// Real-time contract: load_map() is not RT-safe (set-up: it reads files and
// allocates). Every const member function of OccupancyMap is RT-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rack::maps {

enum class CellState : uint8_t { kFree = 0, kOccupied = 1, kUnknown = 2 };

struct RayHit {
  float range = 0.0F;  // metres to the first occupied cell, or max_range when !hit
  bool hit = false;    // false: nothing occupied within max_range (or the ray left the map)
};

class OccupancyMap {
 public:
  OccupancyMap() = default;
  // A map from probabilities in [0, 1] (or < 0 for unknown), row-major with row 0 at
  // the bottom; thresholds as in the YAML. For tests and generated maps.
  OccupancyMap(int width, int height, double resolution, double origin_x, double origin_y, double origin_yaw,
               std::vector<float> occupancy, double occupied_thresh = 0.65, double free_thresh = 0.196);

  [[nodiscard]] int width() const noexcept { return width_; }
  [[nodiscard]] int height() const noexcept { return height_; }
  [[nodiscard]] double resolution() const noexcept { return resolution_; }
  [[nodiscard]] double origin_x() const noexcept { return origin_x_; }
  [[nodiscard]] double origin_y() const noexcept { return origin_y_; }
  [[nodiscard]] double origin_yaw() const noexcept { return origin_yaw_; }
  [[nodiscard]] double occupied_thresh() const noexcept { return occupied_thresh_; }
  [[nodiscard]] double free_thresh() const noexcept { return free_thresh_; }
  // Where the map came from ("" for a map made in memory).
  [[nodiscard]] const std::string& source() const noexcept { return source_; }

  // Occupancy probability of a cell in [0, 1], or -1 for unknown; -1 outside the map.
  [[nodiscard]] float occupancy(int ix, int iy) const noexcept;
  // Free, occupied or unknown (thresholds applied); kUnknown outside the map.
  [[nodiscard]] CellState cell_state(int ix, int iy) const noexcept;
  // The cell holding a map-frame point; false when it lies outside the grid.
  [[nodiscard]] bool world_to_cell(double x, double y, int& ix, int& iy) const noexcept;
  // The map-frame centre of a cell.
  void cell_to_world(int ix, int iy, double& x, double& y) const noexcept;
  [[nodiscard]] CellState state_at(double x, double y) const noexcept;
  // Casts a ray from (x, y) (map frame) along `angle` (radians, map frame) through the
  // grid (exact cell traversal, Amanatides & Woo 1987) and returns the distance to the
  // first occupied cell's boundary. A ray that starts in an occupied cell hits at 0.
  [[nodiscard]] RayHit cast_ray(double x, double y, double angle, double max_range) const noexcept;
  // Number of free cells (global localisation samples among them).
  [[nodiscard]] std::size_t free_cell_count() const noexcept { return free_cells_; }

 private:
  friend struct MapLoader;
  void classify() noexcept;

  int width_ = 0;
  int height_ = 0;
  double resolution_ = 0.0;
  double origin_x_ = 0.0, origin_y_ = 0.0, origin_yaw_ = 0.0;
  double cos_yaw_ = 1.0, sin_yaw_ = 0.0;
  double occupied_thresh_ = 0.65, free_thresh_ = 0.196;
  std::vector<float> occupancy_;   // row-major, row 0 = bottom
  std::vector<CellState> state_;   // the same cells, classified
  std::size_t free_cells_ = 0;
  std::string source_;
};

struct MapError {
  std::string file;
  int line = 0;          // YAML line (1-based), 0 when not about a line
  long byte_offset = -1; // image byte offset, -1 when not about the image
  std::string message;
  // "file:line: message", "file: byte N: message" or "file: message".
  [[nodiscard]] std::string str() const;
};

struct LoadMapResult {
  std::optional<OccupancyMap> map;  // empty when errors is not empty
  std::vector<MapError> errors;
  [[nodiscard]] bool ok() const noexcept { return map.has_value(); }
  [[nodiscard]] std::string error_text() const;  // every error, one per line
};

// Reads a map_server YAML file and its image. Never throws for bad input.
[[nodiscard]] LoadMapResult load_map(const std::string& yaml_path);

// Reads a PGM image (P5 binary with maxval <= 255, or P2 text). Row 0 of `pixels` is
// the image's top row, as stored in the file. Errors name `path` and a byte offset.
struct PgmImage {
  int width = 0;
  int height = 0;
  int maxval = 0;
  std::vector<uint8_t> pixels;
};
[[nodiscard]] std::optional<PgmImage> read_pgm(const std::string& path, std::vector<MapError>& errors);

}  // namespace rack::maps
