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
// error names the file and the YAML line or the image's byte offset. Both files must
// be regular files (a FIFO, a device such as /dev/zero or a directory is refused
// before anything is read) within the limits below, which are checked before
// anything is allocated for the image.
//
// Real-time contract: load_map() is not RT-safe (set-up: it reads files and
// allocates). Every const member function of OccupancyMap is RT-safe.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rack::maps {

// Limits of what load_map() reads (README "Maps").
inline constexpr uint64_t kMaxMapYamlBytes = 1u << 20;       // the YAML file: 1 MiB
inline constexpr uint64_t kMaxMapImageBytes = 256u << 20;    // the PGM file: 256 MiB
inline constexpr long kMaxMapSide = 100000;                  // pixels per side
inline constexpr uint64_t kMaxMapCells = uint64_t{1} << 26;  // width x height: 64 Mi (e.g. 8192 x 8192)

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
  std::vector<float> occupancy_;  // row-major, row 0 = bottom
  std::vector<CellState> state_;  // the same cells, classified
  std::size_t free_cells_ = 0;
  std::string source_;
};

struct MapError {
  std::string file;
  int line = 0;           // YAML line (1-based), 0 when not about a line
  long byte_offset = -1;  // image byte offset, -1 when not about the image
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

// What a map YAML file says (the image path as written, not yet resolved).
struct MapYaml {
  std::string image;
  double resolution = 0.0;
  double origin[3] = {0.0, 0.0, 0.0};
  bool negate = false;
  double occupied_thresh = 0.65, free_thresh = 0.196;
  std::string mode = "trinary";
};
// Parses the YAML text of a map file (`name` for the messages). Never throws: every
// problem is appended to `errors` with the line; empty when there is one.
[[nodiscard]] std::optional<MapYaml> parse_map_yaml(const std::string& name, const std::string& text,
                                                    std::vector<MapError>& errors);

// Reads a PGM image (P5 binary with maxval <= 255, or P2 text). Row 0 of `pixels` is
// the image's top row, as stored in the file. Errors name `path` and a byte offset.
struct PgmImage {
  int width = 0;
  int height = 0;
  int maxval = 0;
  std::vector<uint8_t> pixels;
};
[[nodiscard]] std::optional<PgmImage> read_pgm(const std::string& path, std::vector<MapError>& errors);
// The same for a file's bytes in memory (`name` for the messages). Never throws for bad
// input; allocates at most the pixels a file of this size can hold.
[[nodiscard]] std::optional<PgmImage> parse_pgm(const std::string& name, const std::string& bytes,
                                                std::vector<MapError>& errors);

}  // namespace rack::maps
