#include "rack/maps/occupancy_map.h"

#include <yaml-cpp/yaml.h>

#include "rack/rt/input_file.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <limits>
#include <set>

namespace rack::maps {

// ---- OccupancyMap -------------------------------------------------------------

OccupancyMap::OccupancyMap(int width, int height, double resolution, double origin_x, double origin_y,
                           double origin_yaw, std::vector<float> occupancy, double occupied_thresh, double free_thresh)
    : width_(width),
      height_(height),
      resolution_(resolution),
      origin_x_(origin_x),
      origin_y_(origin_y),
      origin_yaw_(origin_yaw),
      cos_yaw_(std::cos(origin_yaw)),
      sin_yaw_(std::sin(origin_yaw)),
      occupied_thresh_(occupied_thresh),
      free_thresh_(free_thresh),
      occupancy_(std::move(occupancy)) {
  occupancy_.resize(static_cast<std::size_t>(std::max(0, width_)) * static_cast<std::size_t>(std::max(0, height_)),
                    -1.0F);
  classify();
}

void OccupancyMap::classify() noexcept {
  state_.assign(occupancy_.size(), CellState::kUnknown);
  free_cells_ = 0;
  for (std::size_t i = 0; i < occupancy_.size(); ++i) {
    const float p = occupancy_[i];
    if (p < 0.0F) continue;
    if (p > occupied_thresh_) {
      state_[i] = CellState::kOccupied;
    } else if (p < free_thresh_) {
      state_[i] = CellState::kFree;
      ++free_cells_;
    }
  }
}

float OccupancyMap::occupancy(int ix, int iy) const noexcept {
  if (ix < 0 || iy < 0 || ix >= width_ || iy >= height_) return -1.0F;
  return occupancy_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(ix)];
}

CellState OccupancyMap::cell_state(int ix, int iy) const noexcept {
  if (ix < 0 || iy < 0 || ix >= width_ || iy >= height_) return CellState::kUnknown;
  return state_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(ix)];
}

bool OccupancyMap::world_to_cell(double x, double y, int& ix, int& iy) const noexcept {
  if (resolution_ <= 0.0) return false;
  const double dx = x - origin_x_, dy = y - origin_y_;
  const double mx = (cos_yaw_ * dx + sin_yaw_ * dy) / resolution_;
  const double my = (-sin_yaw_ * dx + cos_yaw_ * dy) / resolution_;
  if (!(mx >= 0.0 && my >= 0.0 && mx < width_ && my < height_)) return false;  // also rejects NaN
  ix = static_cast<int>(mx);
  iy = static_cast<int>(my);
  return true;
}

void OccupancyMap::cell_to_world(int ix, int iy, double& x, double& y) const noexcept {
  const double mx = (ix + 0.5) * resolution_, my = (iy + 0.5) * resolution_;
  x = origin_x_ + cos_yaw_ * mx - sin_yaw_ * my;
  y = origin_y_ + sin_yaw_ * mx + cos_yaw_ * my;
}

CellState OccupancyMap::state_at(double x, double y) const noexcept {
  int ix = 0, iy = 0;
  return world_to_cell(x, y, ix, iy) ? cell_state(ix, iy) : CellState::kUnknown;
}

RayHit OccupancyMap::cast_ray(double x, double y, double angle, double max_range) const noexcept {
  RayHit miss{static_cast<float>(max_range), false};
  if (resolution_ <= 0.0 || !(max_range > 0.0)) return miss;
  // Into the grid's own axes, in cells.
  const double dx0 = x - origin_x_, dy0 = y - origin_y_;
  const double px = (cos_yaw_ * dx0 + sin_yaw_ * dy0) / resolution_;
  const double py = (-sin_yaw_ * dx0 + cos_yaw_ * dy0) / resolution_;
  const double a = angle - origin_yaw_;
  const double dx = std::cos(a), dy = std::sin(a);
  if (!(px >= 0.0 && py >= 0.0 && px < width_ && py < height_)) return miss;  // starts outside (or NaN)
  int ix = static_cast<int>(px), iy = static_cast<int>(py);
  const double max_cells = max_range / resolution_;
  if (cell_state(ix, iy) == CellState::kOccupied) return RayHit{0.0F, true};

  const int step_x = dx > 0 ? 1 : -1;
  const int step_y = dy > 0 ? 1 : -1;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // Ray parameter t (in cells travelled) at which the next x / y cell boundary is crossed.
  const double delta_x = dx != 0.0 ? std::abs(1.0 / dx) : kInf;
  const double delta_y = dy != 0.0 ? std::abs(1.0 / dy) : kInf;
  double t_x = dx > 0 ? (ix + 1 - px) * delta_x : dx < 0 ? (px - ix) * delta_x : kInf;
  double t_y = dy > 0 ? (iy + 1 - py) * delta_y : dy < 0 ? (py - iy) * delta_y : kInf;
  for (;;) {
    double t = 0.0;
    if (t_x < t_y) {
      t = t_x;
      t_x += delta_x;
      ix += step_x;
    } else {
      t = t_y;
      t_y += delta_y;
      iy += step_y;
    }
    if (t > max_cells) return miss;
    if (ix < 0 || iy < 0 || ix >= width_ || iy >= height_) return miss;
    if (cell_state(ix, iy) == CellState::kOccupied) return RayHit{static_cast<float>(t * resolution_), true};
  }
}

// ---- errors -------------------------------------------------------------------

std::string MapError::str() const {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + message;
  if (byte_offset >= 0) return file + ": byte " + std::to_string(byte_offset) + ": " + message;
  return file + ": " + message;
}

std::string LoadMapResult::error_text() const {
  std::string out;
  for (const auto& e : errors) out += e.str() + "\n";
  return out;
}

// ---- PGM ----------------------------------------------------------------------

namespace {

// A cursor over the file's bytes that knows its offset, for messages.
struct PgmReader {
  const std::string& path;
  const std::string& bytes;
  std::vector<MapError>& errors;
  std::size_t pos = 0;

  void fail(std::size_t at, const std::string& message) { errors.push_back({path, 0, static_cast<long>(at), message}); }
  // Skips whitespace and '#' comments (allowed between header fields).
  void skip_space() {
    while (pos < bytes.size()) {
      const auto c = static_cast<unsigned char>(bytes[pos]);
      if (c == '#') {
        while (pos < bytes.size() && bytes[pos] != '\n') ++pos;
      } else if (std::isspace(c) != 0) {
        ++pos;
      } else {
        break;
      }
    }
  }
  bool read_int(const char* what, long max, int& out) {
    skip_space();
    const std::size_t start = pos;
    long v = 0;
    while (pos < bytes.size() && std::isdigit(static_cast<unsigned char>(bytes[pos])) != 0) {
      v = v * 10 + (bytes[pos] - '0');
      if (v > max) {
        fail(start, std::string(what) + " is larger than " + std::to_string(max));
        return false;
      }
      ++pos;
    }
    if (pos == start) {
      fail(start, pos >= bytes.size() ? std::string("file ends where the ") + what + " should be"
                                      : std::string("expected the ") + what + " (a decimal number)");
      return false;
    }
    out = static_cast<int>(v);
    return true;
  }
};

}  // namespace

namespace {

// A facility error ("path: reason") as a MapError of that file.
MapError file_error(const std::string& path, const std::string& error) {
  const std::string prefix = path + ": ";
  return {path, 0, -1, error.rfind(prefix, 0) == 0 ? error.substr(prefix.size()) : error};
}

}  // namespace

std::optional<PgmImage> read_pgm(const std::string& path, std::vector<MapError>& errors) {
  std::string bytes, error;
  if (!rt::read_regular_file(path, kMaxMapImageBytes, "map image", bytes, error)) {
    errors.push_back(file_error(path, error));
    return std::nullopt;
  }
  return parse_pgm(path, bytes, errors);
}

std::optional<PgmImage> parse_pgm(const std::string& path, const std::string& bytes, std::vector<MapError>& errors) {
  PgmReader r{path, bytes, errors};
  if (bytes.size() < 2 || bytes[0] != 'P' || (bytes[1] != '5' && bytes[1] != '2')) {
    r.fail(0, "not a PGM image (expected the magic number P5 or P2)");
    return std::nullopt;
  }
  const bool binary = bytes[1] == '5';
  r.pos = 2;
  PgmImage img;
  if (!r.read_int("width", kMaxMapSide, img.width) || !r.read_int("height", kMaxMapSide, img.height) ||
      !r.read_int("maxval", 65535, img.maxval)) {
    return std::nullopt;
  }
  if (img.width == 0 || img.height == 0) {
    r.fail(r.pos, "the image is empty (" + std::to_string(img.width) + "x" + std::to_string(img.height) + ")");
    return std::nullopt;
  }
  if (img.maxval == 0 || img.maxval > 255) {
    r.fail(r.pos, "maxval " + std::to_string(img.maxval) + " is not supported (1..255: 8-bit grey levels)");
    return std::nullopt;
  }
  // Both sides are at most kMaxMapSide: the product fits easily in 64 bits.
  const std::size_t n = static_cast<std::size_t>(img.width) * static_cast<std::size_t>(img.height);
  if (n > kMaxMapCells) {
    r.fail(r.pos, std::to_string(img.width) + "x" + std::to_string(img.height) + " = " + std::to_string(n) +
                      " pixels, more than the limit of " + std::to_string(kMaxMapCells) + " map cells");
    return std::nullopt;
  }
  if (binary) {
    // Exactly one whitespace byte separates the header from the raster.
    if (r.pos >= bytes.size() || std::isspace(static_cast<unsigned char>(bytes[r.pos])) == 0) {
      r.fail(r.pos, "expected one whitespace byte after maxval");
      return std::nullopt;
    }
    ++r.pos;
    // Checked before the raster is allocated: a header may promise anything.
    if (bytes.size() - r.pos < n) {
      r.fail(static_cast<std::size_t>(bytes.size()), "truncated: the raster needs " + std::to_string(n) +
                                                         " bytes from byte " + std::to_string(r.pos) +
                                                         ", the file has " + std::to_string(bytes.size() - r.pos));
      return std::nullopt;
    }
    img.pixels.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto v = static_cast<uint8_t>(bytes[r.pos + i]);
      if (v > img.maxval) {
        r.fail(r.pos + i, "pixel value " + std::to_string(v) + " is above maxval " + std::to_string(img.maxval));
        return std::nullopt;
      }
      img.pixels[i] = v;
    }
  } else {
    // A text pixel takes at least two bytes (a digit and a separator): the file's size
    // bounds what is allocated, whatever the header says.
    img.pixels.reserve(std::min<std::size_t>(n, (bytes.size() - r.pos) / 2 + 1));
    for (std::size_t i = 0; i < n; ++i) {
      int v = 0;
      if (!r.read_int("pixel value", img.maxval, v)) return std::nullopt;
      img.pixels.push_back(static_cast<uint8_t>(v));
    }
  }
  return img;
}

// ---- YAML ---------------------------------------------------------------------

namespace {

struct YamlReader {
  const std::string& file;
  std::vector<MapError>& errors;

  void error(const YAML::Node& n, const std::string& message) {
    errors.push_back({file, n.Mark().line + 1, -1, message});
  }

  std::optional<double> number(const YAML::Node& map, const char* key, bool required) {
    const YAML::Node n = map[key];
    if (!n) {
      if (required) errors.push_back({file, 0, -1, std::string("missing key '") + key + "'"});
      return std::nullopt;
    }
    try {
      if (!n.IsScalar()) throw YAML::Exception(n.Mark(), "");
      const double v = n.as<double>();
      if (!std::isfinite(v)) throw YAML::Exception(n.Mark(), "");
      return v;
    } catch (const YAML::Exception&) {
      error(n, std::string("'") + key + "' must be a finite number");
      return std::nullopt;
    }
  }

  std::optional<MapYaml> parse(const std::string& text) {
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::ParserException& e) {
      errors.push_back({file, e.mark.line + 1, -1, "YAML syntax: " + e.msg});
      return std::nullopt;
    }
    if (!root.IsMap()) {
      errors.push_back({file, root ? root.Mark().line + 1 : 0, -1,
                        "a map file is a YAML mapping with image, resolution, origin, negate, occupied_thresh, "
                        "free_thresh"});
      return std::nullopt;
    }
    static const std::set<std::string> kKnown = {"image",           "resolution",  "origin", "negate",
                                                 "occupied_thresh", "free_thresh", "mode"};
    std::set<std::string> seen;
    for (auto it = root.begin(); it != root.end(); ++it) {
      const std::string key = it->first.IsScalar() ? it->first.Scalar() : std::string();
      if (kKnown.count(key) == 0U) {
        error(it->first, "unknown key '" + key.substr(0, 60) +
                             "' (known: image, resolution, origin, negate, occupied_thresh, free_thresh, mode)");
      } else if (!seen.insert(key).second) {
        error(it->first, "key '" + key + "' appears twice");
      }
    }
    MapYaml m;
    if (const YAML::Node n = root["image"]; !n) {
      errors.push_back({file, 0, -1, "missing key 'image'"});
    } else if (!n.IsScalar() || n.Scalar().empty()) {
      error(n, "'image' must name the PGM file");
    } else if (n.Scalar().find('\0') != std::string::npos) {
      error(n, "'image' holds a NUL byte");
    } else {
      m.image = n.Scalar();
    }
    const auto resolution = number(root, "resolution", true);
    if (resolution && *resolution <= 0.0) error(root["resolution"], "'resolution' must be positive (metres per pixel)");
    if (resolution) m.resolution = *resolution;
    if (const YAML::Node n = root["origin"]; !n) {
      errors.push_back({file, 0, -1, "missing key 'origin'"});
    } else if (!n.IsSequence() || n.size() != 3) {
      error(n, "'origin' must be [x, y, yaw]");
    } else {
      for (std::size_t i = 0; i < 3; ++i) {
        try {
          if (!n[i].IsScalar()) throw YAML::Exception(n[i].Mark(), "");
          m.origin[i] = n[i].as<double>();
          if (!std::isfinite(m.origin[i])) throw YAML::Exception(n[i].Mark(), "");
        } catch (const YAML::Exception&) {
          error(n[i], "'origin' entries must be finite numbers");
        }
      }
    }
    if (const YAML::Node n = root["negate"]; !n) {
      errors.push_back({file, 0, -1, "missing key 'negate' (0 or 1)"});
    } else {
      const std::string s = n.IsScalar() ? n.Scalar() : std::string("(not a scalar)");
      if (s == "0" || s == "false") {
        m.negate = false;
      } else if (s == "1" || s == "true") {
        m.negate = true;
      } else {
        error(n, "'negate' must be 0 or 1, got '" + s.substr(0, 60) + "'");
      }
    }
    const auto occ = number(root, "occupied_thresh", true);
    const auto fre = number(root, "free_thresh", true);
    if (occ && (*occ < 0.0 || *occ > 1.0)) error(root["occupied_thresh"], "'occupied_thresh' must be in [0, 1]");
    if (fre && (*fre < 0.0 || *fre > 1.0)) error(root["free_thresh"], "'free_thresh' must be in [0, 1]");
    if (occ && fre && *fre > *occ) error(root["free_thresh"], "'free_thresh' is above 'occupied_thresh'");
    if (occ) m.occupied_thresh = *occ;
    if (fre) m.free_thresh = *fre;
    if (const YAML::Node n = root["mode"]; n) {
      m.mode = n.IsScalar() ? n.Scalar() : std::string("(not a scalar)");
      if (m.mode != "trinary" && m.mode != "scale" && m.mode != "raw") {
        error(n, "'mode' must be trinary, scale or raw, got '" + m.mode.substr(0, 60) + "'");
      }
    }
    if (!errors.empty()) return std::nullopt;
    return m;
  }
};

}  // namespace

std::optional<MapYaml> parse_map_yaml(const std::string& name, const std::string& text, std::vector<MapError>& errors) {
  const std::size_t before = errors.size();
  std::vector<MapError> mine;
  std::optional<MapYaml> m;
  try {
    m = YamlReader{name, mine}.parse(text);
  } catch (const std::exception& e) {  // yaml-cpp (deep nesting, conversions) or allocation
    mine.push_back({name, 0, -1, std::string("cannot read the map file: ") + e.what()});
  }
  errors.insert(errors.end(), mine.begin(), mine.end());
  if (errors.size() != before) return std::nullopt;
  return m;
}

struct MapLoader {
  static std::optional<OccupancyMap> load(const std::string& file, std::vector<MapError>& errors) {
    std::string text, error;
    if (!rt::read_regular_file(file, kMaxMapYamlBytes, "map file", text, error)) {
      errors.push_back(file_error(file, error));
      return std::nullopt;
    }
    const std::optional<MapYaml> y = parse_map_yaml(file, text, errors);
    if (!y) return std::nullopt;

    namespace fs = std::filesystem;
    fs::path image_path(y->image);
    if (image_path.is_relative()) image_path = fs::path(file).parent_path() / image_path;
    const auto img = read_pgm(image_path.string(), errors);
    if (!img) return std::nullopt;

    std::vector<float> occupancy(img->pixels.size());
    const auto w = static_cast<std::size_t>(img->width), h = static_cast<std::size_t>(img->height);
    const auto maxval = static_cast<float>(img->maxval);
    for (std::size_t row = 0; row < h; ++row) {
      const std::size_t iy = h - 1 - row;  // image top row = highest y
      for (std::size_t ix = 0; ix < w; ++ix) {
        const float v = img->pixels[row * w + ix];
        float p = 0.0F;
        if (y->mode == "raw") {
          p = v / 100.0F;  // raw: pixel values are occupancy percentages, >100 unknown
          if (v > 100.0F) p = -1.0F;
        } else {
          p = y->negate ? v / maxval : (maxval - v) / maxval;
        }
        occupancy[iy * w + ix] = p;
      }
    }
    OccupancyMap map(img->width, img->height, y->resolution, y->origin[0], y->origin[1], y->origin[2],
                     std::move(occupancy), y->occupied_thresh, y->free_thresh);
    map.source_ = file;
    return map;
  }
};

LoadMapResult load_map(const std::string& yaml_path) {
  LoadMapResult result;
  try {
    auto map = MapLoader::load(yaml_path, result.errors);
    if (result.errors.empty()) result.map = std::move(map);
  } catch (const std::exception& e) {  // allocation: report, never escape
    result.errors.push_back({yaml_path, 0, -1, std::string("cannot load the map: ") + e.what()});
  }
  if (!result.errors.empty()) result.map.reset();
  return result;
}

}  // namespace rack::maps
