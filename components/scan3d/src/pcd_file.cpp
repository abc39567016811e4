#include "rack/scan3d/pcd_file.h"

#include "rack/rt/input_file.h"
#include "scan3d/scan3d_types.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>

namespace rack::scan3d {

namespace {

struct Field {
  std::string name;
  uint32_t size = 4;
  char type = 'F';
  uint32_t count = 1;
  uint64_t offset = 0;  // bytes into a binary point
  uint64_t column = 0;  // first token of an ASCII line
};

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  std::string t;
  while (in >> t) out.push_back(t);
  return out;
}

bool parse_uint(const std::string& s, uint64_t& v) {
  if (s.empty() || s[0] == '-' || s[0] == '+') return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtoull(s.c_str(), &end, 10);
  return errno == 0 && end != s.c_str() && *end == '\0';
}

// One binary value of a field as a double.
double decode(const unsigned char* p, const Field& f) {
  switch (f.type) {
    case 'F':
      if (f.size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      }
      {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    case 'U':
      if (f.size == 1) return p[0];
      if (f.size == 2) {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
      }
      {
        uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
    default:  // 'I'
      if (f.size == 1) return static_cast<int8_t>(p[0]);
      if (f.size == 2) {
        int16_t v;
        std::memcpy(&v, p, 2);
        return v;
      }
      {
        int32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
  }
}

// LZF (the compressor of PCL's binary_compressed PCD data), decoded with every
// reference and length checked against both buffers. A stream is a sequence of
// control bytes: below 32, a run of (ctrl + 1) literal bytes follows; otherwise a
// back reference: length (ctrl >> 5) + 2 (an extra length byte when that field is 7),
// offset ((ctrl & 31) << 8) + next byte + 1 behind the output position. Returns the
// bytes written, or an empty error on success.
std::string lzf_decompress(const unsigned char* in, std::size_t in_len, unsigned char* out, std::size_t out_len,
                           std::size_t& written) {
  std::size_t ip = 0, op = 0;
  while (ip < in_len) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {
      const std::size_t len = ctrl + 1;
      if (ip + len > in_len) return "a literal run of " + std::to_string(len) + " bytes runs past the compressed data";
      if (op + len > out_len) return "the data decompresses to more than the declared size";
      std::memcpy(out + op, in + ip, len);
      ip += len;
      op += len;
      continue;
    }
    std::size_t len = ctrl >> 5;
    if (len == 7) {
      if (ip >= in_len) return "a back reference is cut off";
      len += in[ip++];
    }
    len += 2;
    if (ip >= in_len) return "a back reference is cut off";
    const std::size_t back = ((static_cast<std::size_t>(ctrl & 31) << 8) | in[ip++]) + 1;
    if (back > op) return "a back reference points before the start of the data";
    if (op + len > out_len) return "the data decompresses to more than the declared size";
    for (std::size_t k = 0; k < len; ++k, ++op) out[op] = out[op - back];  // may overlap: byte by byte
  }
  written = op;
  return {};
}

}  // namespace

bool parse_pcd(const std::string& name, const std::string& contents, PcdCloud& out, std::string& error) {
  out = PcdCloud{};
  std::vector<Field> fields;
  bool have_size = false, have_type = false, have_count = false;
  uint64_t width = 0, height = 1, points = 0;
  bool have_width = false, have_points = false;
  std::string data;
  std::size_t pos = 0;
  int line_no = 0;
  const auto fail = [&](int line, const std::string& what) {
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict, its bug 105329) about
    // a temporary ":" + std::to_string(...).
    error = name;
    if (line > 0) error.append(":").append(std::to_string(line));
    error.append(": ").append(what);
    return false;
  };
  // Header: one keyword per line, up to DATA.
  while (data.empty()) {
    if (pos >= contents.size()) return fail(line_no, "header ends without a DATA line (not a PCD file?)");
    std::size_t eol = contents.find('\n', pos);
    if (eol == std::string::npos) eol = contents.size();
    std::string line = contents.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    const std::vector<std::string> t = split(line);
    if (t.empty()) continue;
    const std::string& key = t[0];
    const std::size_t n = t.size() - 1;
    if (key == "VERSION") continue;
    if (key == "FIELDS" || key == "COLUMNS") {
      if (n == 0) return fail(line_no, "FIELDS names no field");
      if (n > kMaxPcdFields) {
        return fail(line_no, "FIELDS names " + std::to_string(n) + " fields, more than the limit of " +
                                 std::to_string(kMaxPcdFields));
      }
      fields.clear();
      for (std::size_t i = 1; i < t.size(); ++i) fields.push_back(Field{t[i]});
    } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
      if (fields.empty()) return fail(line_no, key + " before FIELDS");
      if (n != fields.size()) {
        return fail(line_no,
                    key + " has " + std::to_string(n) + " entries, FIELDS has " + std::to_string(fields.size()));
      }
      for (std::size_t i = 0; i < n; ++i) {
        const std::string& v = t[i + 1];
        if (key == "TYPE") {
          if (v.size() != 1 || (v[0] != 'F' && v[0] != 'U' && v[0] != 'I')) {
            return fail(line_no, "TYPE of field '" + fields[i].name + "' is '" + v + "' (F, U or I)");
          }
          fields[i].type = v[0];
        } else {
          uint64_t u = 0;
          if (!parse_uint(v, u) || u == 0 || u > 1'000'000) {
            return fail(line_no, key + " of field '" + fields[i].name + "' is '" + v + "' (a positive integer)");
          }
          if (key == "SIZE") {
            if (u != 1 && u != 2 && u != 4 && u != 8) {
              return fail(line_no, "SIZE of field '" + fields[i].name + "' is " + v + " (1, 2, 4 or 8)");
            }
            fields[i].size = static_cast<uint32_t>(u);
          } else {
            fields[i].count = static_cast<uint32_t>(u);
          }
        }
      }
      (key == "SIZE" ? have_size : key == "TYPE" ? have_type : have_count) = true;
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      uint64_t u = 0;
      if (n != 1 || !parse_uint(t[1], u)) {
        return fail(line_no,
                    key + " must be one non-negative integer, got '" + (n ? t[1].substr(0, 40) : std::string()) + "'");
      }
      if (u > kMaxPcdPoints) {
        return fail(line_no,
                    key + " " + t[1] + " is more than the limit of " + std::to_string(kMaxPcdPoints) + " points");
      }
      if (key == "WIDTH") {
        width = u;
        have_width = true;
      } else if (key == "HEIGHT") height = u;
      else {
        points = u;
        have_points = true;
      }
    } else if (key == "VIEWPOINT") {
      if (n != 7) return fail(line_no, "VIEWPOINT needs 7 numbers (tx ty tz qw qx qy qz), got " + std::to_string(n));
    } else if (key == "DATA") {
      if (n != 1) return fail(line_no, "DATA needs one of ascii, binary, binary_compressed");
      data = t[1];
      if (data != "ascii" && data != "binary" && data != "binary_compressed") {
        return fail(line_no, "DATA '" + data + "' is not ascii, binary or binary_compressed");
      }
    } else {
      return fail(line_no, "unknown header keyword '" + key + "'");
    }
  }
  const int data_line = line_no;
  if (fields.empty()) return fail(data_line, "no FIELDS line before DATA");
  if (!have_size || !have_type) return fail(data_line, "SIZE and TYPE lines are required before DATA");
  (void)have_count;  // COUNT defaults to 1 per field
  if (!have_width) return fail(data_line, "no WIDTH line before DATA");
  // Each at most kMaxPcdPoints: the product fits in 64 bits.
  if (width * height > kMaxPcdPoints) {
    return fail(data_line, "WIDTH x HEIGHT = " + std::to_string(width * height) + " points, more than the limit of " +
                               std::to_string(kMaxPcdPoints));
  }
  if (!have_points) points = width * height;
  if (points != width * height) {
    return fail(data_line,
                "POINTS " + std::to_string(points) + " is not WIDTH x HEIGHT = " + std::to_string(width * height));
  }
  int ix = -1, iy = -1, iz = -1, ii = -1;
  // 64 bits, bounded per field (SIZE <= 8, COUNT <= 1e6, at most kMaxPcdFields): the
  // sums cannot wrap; a point larger than kMaxPcdPointBytes is refused below.
  uint64_t offset = 0, column = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    Field& f = fields[i];
    if ((f.type == 'F' && f.size != 4 && f.size != 8) || (f.type != 'F' && f.size == 8)) {
      return fail(data_line, "field '" + f.name + "': TYPE " + std::string(1, f.type) + " with SIZE " +
                                 std::to_string(f.size) + " is not a PCD type");
    }
    f.offset = offset;
    f.column = column;
    offset += f.size * f.count;
    column += f.count;
    if (f.name == "x") ix = static_cast<int>(i);
    else if (f.name == "y") iy = static_cast<int>(i);
    else if (f.name == "z") iz = static_cast<int>(i);
    else if (f.name == "intensity" || f.name == "i") ii = static_cast<int>(i);
  }
  if (ix < 0 || iy < 0 || iz < 0) return fail(data_line, "FIELDS must include x, y and z");
  if (offset > kMaxPcdPointBytes) {
    return fail(data_line, "a point of these FIELDS, SIZE and COUNT takes " + std::to_string(offset) +
                               " bytes, more than the limit of " + std::to_string(kMaxPcdPointBytes));
  }
  out.declared_points = static_cast<uint32_t>(points);
  // points <= kMaxPcdPoints and offset <= kMaxPcdPointBytes: no wrap-around in 64 bits.
  const uint64_t need = points * offset;
  const std::size_t have = contents.size() >= pos ? contents.size() - pos : 0;
  // A hint only, bounded by what the data can hold: POINTS comes from the file and may
  // lie (an ASCII point takes at least two bytes per value).
  const uint64_t fit = data == "ascii" ? have / (2 * column) + 1 : data == "binary" ? have / offset + 1 : points;
  const std::size_t expect = static_cast<std::size_t>(std::min<uint64_t>(points, fit));
  const auto reserve_points = [&](std::size_t n) {
    out.x.reserve(n);
    out.y.reserve(n);
    out.z.reserve(n);
    out.intensity.reserve(n);
  };
  // Beyond float's range is not finite either (a double field of 1e300 would become
  // inf, and the conversion itself is undefined): such points are left out too.
  const auto to_float = [](double v, float& f) {
    if (!(std::fabs(v) <= static_cast<double>(std::numeric_limits<float>::max()))) return false;  // also NaN
    f = static_cast<float>(v);
    return true;
  };
  const auto keep = [&](double x, double y, double z, double in) {
    float fx = 0, fy = 0, fz = 0, fi = 0;
    if (!to_float(x, fx) || !to_float(y, fy) || !to_float(z, fz)) {
      ++out.non_finite;
      return;
    }
    out.x.push_back(fx);
    out.y.push_back(fy);
    out.z.push_back(fz);
    out.intensity.push_back(to_float(in, fi) ? fi : 0.0F);
  };
  if (data == "binary_compressed") {
    // Two uint32 (compressed and raw size), then LZF data that holds the fields one
    // after another (all x, then all y, ...), not point by point.
    if (have < 8)
      return fail(0, "binary_compressed data: " + std::to_string(have) + " bytes, no size header (truncated file?)");
    uint32_t packed = 0, raw = 0;
    std::memcpy(&packed, contents.data() + pos, 4);
    std::memcpy(&raw, contents.data() + pos + 4, 4);
    if (raw != need) {
      return fail(0, "binary_compressed data: raw size " + std::to_string(raw) + ", the header needs " +
                         std::to_string(points) + " points x " + std::to_string(offset) +
                         " bytes = " + std::to_string(need));
    }
    // LZF expands at most about 90 times (3 bytes for a 264-byte reference): a raw
    // size beyond that is a lie, refused before anything is allocated for it.
    if (static_cast<uint64_t>(raw) > static_cast<uint64_t>(packed) * 100 + 64) {
      return fail(0, "binary_compressed data: raw size " + std::to_string(raw) + " from " + std::to_string(packed) +
                         " compressed bytes is more than LZF can expand (corrupt file?)");
    }
    if (raw > kMaxPcdRawBytes) {
      return fail(0, "binary_compressed data: raw size " + std::to_string(raw) + " is more than the limit of " +
                         std::to_string(kMaxPcdRawBytes) + " bytes");
    }
    if (have - 8 < packed) {
      return fail(0, "binary_compressed data: " + std::to_string(have - 8) + " bytes after the sizes, " +
                         std::to_string(packed) + " declared (truncated file?)");
    }
    std::vector<unsigned char> buf(static_cast<std::size_t>(need));
    reserve_points(expect);
    std::size_t written = 0;
    const std::string why = lzf_decompress(reinterpret_cast<const unsigned char*>(contents.data() + pos + 8), packed,
                                           buf.data(), buf.size(), written);
    if (!why.empty()) return fail(0, "binary_compressed data: " + why + " (corrupt file?)");
    if (written != need) {
      return fail(0, "binary_compressed data: decompresses to " + std::to_string(written) +
                         " bytes, the header needs " + std::to_string(need));
    }
    // Field f of point p: at points * (the bytes of the fields before f) + p * its own size.
    const auto column_of = [&](int index) -> const unsigned char* {
      return buf.data() + static_cast<std::size_t>(points) * fields[static_cast<std::size_t>(index)].offset;
    };
    const Field& fx = fields[static_cast<std::size_t>(ix)];
    const Field& fy = fields[static_cast<std::size_t>(iy)];
    const Field& fz = fields[static_cast<std::size_t>(iz)];
    const Field* fi = ii >= 0 ? &fields[static_cast<std::size_t>(ii)] : nullptr;
    const unsigned char *cx = column_of(ix), *cy = column_of(iy), *cz = column_of(iz);
    const unsigned char* ci = fi != nullptr ? column_of(ii) : nullptr;
    for (uint64_t q = 0; q < points; ++q) {
      keep(decode(cx + q * fx.size * fx.count, fx), decode(cy + q * fy.size * fy.count, fy),
           decode(cz + q * fz.size * fz.count, fz), fi != nullptr ? decode(ci + q * fi->size * fi->count, *fi) : 0.0);
    }
    return true;
  }
  if (data == "binary") {
    if (have < need) {
      return fail(0, "binary data holds " + std::to_string(have) + " bytes, the header needs " +
                         std::to_string(points) + " points x " + std::to_string(offset) +
                         " bytes = " + std::to_string(need) + " (truncated file?)");
    }
    reserve_points(expect);
    const auto* base = reinterpret_cast<const unsigned char*>(contents.data() + pos);
    const Field& fx = fields[static_cast<std::size_t>(ix)];
    const Field& fy = fields[static_cast<std::size_t>(iy)];
    const Field& fz = fields[static_cast<std::size_t>(iz)];
    const Field* fi = ii >= 0 ? &fields[static_cast<std::size_t>(ii)] : nullptr;
    for (uint64_t p = 0; p < points; ++p) {
      const unsigned char* pt = base + p * offset;
      keep(decode(pt + fx.offset, fx), decode(pt + fy.offset, fy), decode(pt + fz.offset, fz),
           fi != nullptr ? decode(pt + fi->offset, *fi) : 0.0);
    }
    return true;
  }
  // ASCII: one point per line, every value checked.
  reserve_points(expect);
  uint64_t p = 0;
  std::vector<std::string> t;
  while (pos < contents.size()) {
    std::size_t eol = contents.find('\n', pos);
    if (eol == std::string::npos) eol = contents.size();
    std::string line = contents.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    t = split(line);
    if (t.empty()) continue;
    if (p >= points) return fail(line_no, "more points than POINTS " + std::to_string(points));
    if (t.size() != column) {
      return fail(line_no, "point " + std::to_string(p) + " has " + std::to_string(t.size()) + " values, FIELDS need " +
                               std::to_string(column));
    }
    double v[4] = {0, 0, 0, 0};
    const int idx[4] = {ix, iy, iz, ii};
    for (int k = 0; k < 4; ++k) {
      if (idx[k] < 0) continue;
      const Field& f = fields[static_cast<std::size_t>(idx[k])];
      const std::string& s = t[f.column];
      char* end = nullptr;
      v[k] = std::strtod(s.c_str(), &end);
      if (end == s.c_str() || *end != '\0') {
        return fail(line_no, "point " + std::to_string(p) + ", field '" + f.name + "': '" + s + "' is not a number");
      }
    }
    keep(v[0], v[1], v[2], v[3]);
    ++p;
  }
  if (p != points)
    return fail(line_no, "file ends after " + std::to_string(p) + " of " + std::to_string(points) + " points");
  return true;
}

bool read_pcd(const std::string& path, PcdCloud& out, std::string& error) {
  out = PcdCloud{};
  std::string contents;
  if (!rt::read_regular_file(path, kMaxPcdFileBytes, "PCD file", contents, error)) return false;
  try {
    return parse_pcd(path, contents, out, error);
  } catch (const std::exception& e) {  // allocation within the limits failed: refused, never past here
    out = PcdCloud{};
    error = path + ": " + e.what();
    return false;
  }
}

bool write_pcd(const std::string& path, const interfaces::Scan3dData& scan, std::string& error) {
  const uint32_t n = std::min(scan.point_count, interfaces::kScan3dMaxPoints);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    error = path + ": cannot create: " + std::strerror(errno);
    return false;
  }
  std::fprintf(f,
               "# .PCD v0.7 - Point Cloud Data file format (RACK-RT Scan3D scan %u; type: rack/interfaces/robot.h "
               "kScanPoint*)\nVERSION 0.7\nFIELDS x y z intensity type\nSIZE 4 4 4 4 1\nTYPE F F F F U\n"
               "COUNT 1 1 1 1 1\nWIDTH %u\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %u\nDATA binary\n",
               scan.scan_number, n, n);
  bool ok = true;
  for (uint32_t i = 0; i < n && ok; ++i) {
    unsigned char rec[17];
    std::memcpy(rec, &scan.x[i], 4);
    std::memcpy(rec + 4, &scan.y[i], 4);
    std::memcpy(rec + 8, &scan.z[i], 4);
    std::memcpy(rec + 12, &scan.intensity[i], 4);
    rec[16] = scan.type[i];
    ok = std::fwrite(rec, sizeof rec, 1, f) == 1;
  }
  const int saved = errno;
  if (std::fclose(f) != 0 || !ok) {
    error = path + ": write failed: " + std::strerror(ok ? errno : saved);
    return false;
  }
  return true;
}

}  // namespace rack::scan3d
