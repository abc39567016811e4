// PCD files (PCL's point cloud format, version 0.7 and 0.6): reading for Scan3D's
// file source, writing for its STORE_DATA command. Our own strict reader rather than
// PCL's: PCL's reader warns and carries on past a malformed line (and its io library
// drags VTK into every process that links it); this one rejects a file with
// `file:line: what` for the header and for every ASCII point, or the byte counts for
// binary data. DATA ascii, binary and binary_compressed (LZF, as PCL writes it with
// savePCDFileBinaryCompressed) are read; corrupt compressed data is refused with
// what is wrong, never read past its buffers.
// Fields x, y, z are required; intensity (or i) is used when present; every other
// field is read past. Points with a non-finite coordinate (organised clouds' holes)
// are left out.
//
// Limits, checked before anything is allocated for the data (README "Scan3D"): the
// file must be a regular file (a FIFO or device is refused without blocking) of at
// most kMaxPcdFileBytes; WIDTH, HEIGHT, POINTS and WIDTH x HEIGHT at most
// kMaxPcdPoints; at most kMaxPcdFields fields; one point at most kMaxPcdPointBytes;
// binary_compressed data at most kMaxPcdRawBytes once decompressed.
//
// Real-time contract: not RT-safe (file I/O, allocation). Call from non-RT code
// (Scan3D's data task runs at normal priority).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "scan3d/scan3d_types.h"

namespace rack::scan3d {

inline constexpr uint64_t kMaxPcdFileBytes = 256u << 20;  // 256 MiB
inline constexpr uint64_t kMaxPcdPoints = 10'000'000;
inline constexpr std::size_t kMaxPcdFields = 1000;
inline constexpr uint64_t kMaxPcdPointBytes = 65536;
inline constexpr uint64_t kMaxPcdRawBytes = 256u << 20;  // 256 MiB

struct PcdCloud {
  std::vector<float> x, y, z, intensity;
  uint32_t declared_points = 0;  // POINTS in the header
  uint32_t non_finite = 0;       // points left out
  [[nodiscard]] std::size_t size() const noexcept { return x.size(); }
};

// Reads `path` into `out`. false with `error` = "path:line: reason" (or "path: reason").
// Never throws for bad input.
[[nodiscard]] bool read_pcd(const std::string& path, PcdCloud& out, std::string& error);
// The same for a file's contents already in memory (`name` for the messages). Throws
// only std::bad_alloc (allocations stay within the limits above).
[[nodiscard]] bool parse_pcd(const std::string& name, const std::string& contents, PcdCloud& out, std::string& error);

// Writes a Scan3D sample's points as a binary PCD file (FIELDS x y z intensity type).
// false with `error` naming the file and errno's text.
[[nodiscard]] bool write_pcd(const std::string& path, const interfaces::Scan3dData& scan, std::string& error);

}  // namespace rack::scan3d
