// Scan3D's processing of one assembled 3-D scan, on PCL: voxel-grid downsampling,
// statistical outlier removal, a bound on the point count, RANSAC ground-plane
// segmentation (a plane near z = 0 whose normal is within ground_max_tilt of
// vertical) and the point types: ground (within ground_tolerance of the plane),
// ceiling (more than ceiling_height above it), objects (kScanPointObstacle: the rest).
// And the range image of a scan (pcl::RangeImage) for GET_RANGE_IMAGE.
//
// PCL stays behind this header (a pimpl): nothing that includes it sees PCL.
//
// Real-time contract: NOT RT-safe (PCL allocates); Scan3D runs it in its data task at
// normal priority (priority 0), as MCL runs MRPT. One thread per pipeline object.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "scan3d/scan3d_types.h"

namespace rack::scan3d {

struct PipelineOptions {
  double voxel_size = 0.05;        // m, voxel grid leaf (0: no downsampling)
  int outlier_neighbours = 16;     // statistical outlier removal: k neighbours (0: off)
  double outlier_std = 2.0;        // ... remove points whose mean distance is above mean + this * std dev
  double ground_tolerance = 0.05;  // m, RANSAC inlier distance; points this close to the plane are ground
  double ground_max_tilt = 0.2;    // rad, the plane's normal may be this far from vertical
  double ground_max_height = 0.3;  // m, only points with |z| below this are ground candidates
  int ransac_iterations = 200;
  uint32_t ground_min_points = 30;  // fewer inliers: no ground plane
  double ceiling_height = 0.0;      // m above the ground plane; higher points are ceiling (0: no ceiling)
  uint32_t max_points = interfaces::kScan3dMaxPoints;  // evenly thinned above this
};
// Throws std::invalid_argument naming the bad option.
void validate(const PipelineOptions& o);
// The same checks without throwing: nullptr, or the (static) reason. RT-safe.
[[nodiscard]] const char* check_options(const PipelineOptions& o) noexcept;

class Scan3dPipeline {
 public:
  Scan3dPipeline();
  ~Scan3dPipeline();
  Scan3dPipeline(const Scan3dPipeline&) = delete;
  Scan3dPipeline& operator=(const Scan3dPipeline&) = delete;

  // Processes n points (robot frame; intensity may be nullptr) into `out`: points,
  // types, point_count, raw_points, ground/object/ceiling counts, the ground plane and
  // process_ms. Leaves out's other fields alone.
  void process(const float* x, const float* y, const float* z, const float* intensity, std::size_t n,
               const PipelineOptions& options, interfaces::Scan3dData& out);

  // The range image of `scan` seen from (sx, sy, sz) (robot frame) at `resolution`
  // rad per pixel: row 0 at the top, column 0 at the left. false with `error` when the
  // scan is empty or the image would exceed kScan3dRangeImageMaxPixels.
  static bool range_image(const interfaces::Scan3dData& scan, double sx, double sy, double sz, double resolution,
                          interfaces::Scan3dRangeImage& out, std::string& error);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rack::scan3d
