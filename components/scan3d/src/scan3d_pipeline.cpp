// The only translation unit of Scan3D that includes PCL (PCL's headers are slow to
// compile; keep it that way).
#include "rack/scan3d/scan3d_pipeline.h"

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/range_image/range_image.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "scan3d/scan3d_types.h"
#include "rack/interfaces/robot.h"

namespace rack::scan3d {

constexpr double kMinRangeImageResolution = 0.2 * M_PI / 180.0;

using Cloud = pcl::PointCloud<pcl::PointXYZI>;

const char* check_options(const PipelineOptions& o) noexcept {
  if (!(o.voxel_size >= 0.0)) return "voxel_size must be >= 0";
  if (o.voxel_size > 0.0 && o.voxel_size < 1e-3) return "voxel_size below 1 mm overflows PCL's voxel grid index";
  if (o.outlier_neighbours < 0) return "outlier_neighbours must be >= 0";
  if (!(o.outlier_std > 0.0)) return "outlier_std must be > 0";
  if (!(o.ground_tolerance > 0.0)) return "ground_tolerance must be > 0";
  if (!(o.ground_max_tilt > 0.0 && o.ground_max_tilt < 1.5)) return "ground_max_tilt must be in (0, 1.5) rad";
  if (!(o.ground_max_height > 0.0)) return "ground_max_height must be > 0";
  if (o.ransac_iterations < 1) return "ransac_iterations must be >= 1";
  if (!(o.ceiling_height >= 0.0)) return "ceiling_height must be >= 0";
  if (o.max_points == 0 || o.max_points > interfaces::kScan3dMaxPoints)
    return "max_points must be in 1..kScan3dMaxPoints";
  return nullptr;
}

void validate(const PipelineOptions& o) {
  if (const char* why = check_options(o)) throw std::invalid_argument(why);
}

struct Scan3dPipeline::Impl {
  // Reused between scans: their capacity grows to the largest scan once.
  Cloud::Ptr input{new Cloud};
  Cloud::Ptr voxels{new Cloud};
  Cloud::Ptr cleaned{new Cloud};
  pcl::Indices candidates;
};

Scan3dPipeline::Scan3dPipeline() : impl_(std::make_unique<Impl>()) {}
Scan3dPipeline::~Scan3dPipeline() = default;

void Scan3dPipeline::process(const float* x, const float* y, const float* z, const float* intensity, std::size_t n,
                             const PipelineOptions& o, interfaces::Scan3dData& out) {
  const auto start = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  Cloud& in = *m.input;
  in.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    pcl::PointXYZI& p = in[i];
    p.x = x[i];
    p.y = y[i];
    p.z = z[i];
    p.intensity = intensity != nullptr ? intensity[i] : 0.0F;
  }
  in.width = static_cast<uint32_t>(n);
  in.height = 1;
  in.is_dense = true;

  Cloud::Ptr current = m.input;
  if (o.voxel_size > 0.0 && n > 0) {
    pcl::VoxelGrid<pcl::PointXYZI> grid;
    grid.setInputCloud(current);
    const auto leaf = static_cast<float>(o.voxel_size);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.filter(*m.voxels);
    current = m.voxels;
  }
  if (o.outlier_neighbours > 0 && current->size() > static_cast<std::size_t>(o.outlier_neighbours)) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZI> sor;
    sor.setInputCloud(current);
    sor.setMeanK(o.outlier_neighbours);
    sor.setStddevMulThresh(o.outlier_std);
    sor.filter(*m.cleaned);
    current = m.cleaned;
  }
  Cloud& c = *current;
  // Bound the count: keep every k-th point (even thinning keeps the shape).
  const std::size_t limit = std::min<std::size_t>(o.max_points, interfaces::kScan3dMaxPoints);
  if (c.size() > limit) {
    const double step = static_cast<double>(c.size()) / static_cast<double>(limit);
    for (std::size_t i = 0; i < limit; ++i) c[i] = c[static_cast<std::size_t>(static_cast<double>(i) * step)];
    c.resize(limit);
  }

  // Ground plane: RANSAC on the points near z = 0, a plane perpendicular to z.
  m.candidates.clear();
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (std::fabs(c[i].z) <= o.ground_max_height) m.candidates.push_back(static_cast<pcl::index_t>(i));
  }
  bool have_plane = false;
  float a = 0, b = 0, cc = 1, d = 0;
  if (m.candidates.size() >= std::max<uint32_t>(o.ground_min_points, 3)) {
    pcl::SACSegmentation<pcl::PointXYZI> seg;
    seg.setOptimizeCoefficients(true);
    seg.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
    seg.setMethodType(pcl::SAC_RANSAC);
    seg.setAxis(Eigen::Vector3f(0.0F, 0.0F, 1.0F));
    seg.setEpsAngle(o.ground_max_tilt);
    seg.setDistanceThreshold(o.ground_tolerance);
    seg.setMaxIterations(o.ransac_iterations);
    seg.setInputCloud(current);
    seg.setIndices(pcl::IndicesPtr(new pcl::Indices(m.candidates)));
    pcl::PointIndices inliers;
    pcl::ModelCoefficients coeff;
    seg.segment(inliers, coeff);
    if (inliers.indices.size() >= o.ground_min_points && coeff.values.size() == 4) {
      a = coeff.values[0];
      b = coeff.values[1];
      cc = coeff.values[2];
      d = coeff.values[3];
      const float norm = std::sqrt(a * a + b * b + cc * cc);
      if (norm > 0.0F && std::isfinite(norm)) {
        const float s = (cc < 0.0F ? -1.0F : 1.0F) / norm;  // normal up: height = signed distance
        a *= s;
        b *= s;
        cc *= s;
        d *= s;
        have_plane = true;
      }
    }
  }

  const auto count = static_cast<uint32_t>(c.size());
  uint32_t ground = 0, objects = 0, ceiling = 0;
  const auto tol = static_cast<float>(o.ground_tolerance);
  const auto ceil_h = static_cast<float>(o.ceiling_height);
  for (uint32_t i = 0; i < count; ++i) {
    const pcl::PointXYZI& p = c[i];
    out.x[i] = p.x;
    out.y[i] = p.y;
    out.z[i] = p.z;
    out.intensity[i] = p.intensity;
    uint8_t type = interfaces::kScanPointNormal;
    if (have_plane) {
      const float h = a * p.x + b * p.y + cc * p.z + d;
      if (std::fabs(h) <= tol) {
        type = interfaces::kScanPointGround;
        ++ground;
      } else if (ceil_h > 0.0F && h > ceil_h) {
        type = interfaces::kScanPointCeiling;
        ++ceiling;
      } else {
        type = interfaces::kScanPointObstacle;
        ++objects;
      }
    }
    out.type[i] = type;
  }
  out.point_count = count;
  out.raw_points = static_cast<uint32_t>(n);
  out.ground_points = ground;
  out.object_points = objects;
  out.ceiling_points = ceiling;
  out.ground_valid = have_plane ? 1 : 0;
  out.ground_a = have_plane ? a : 0.0F;
  out.ground_b = have_plane ? b : 0.0F;
  out.ground_c = have_plane ? cc : 0.0F;
  out.ground_d = have_plane ? d : 0.0F;
  out.process_ms = std::chrono::duration<float, std::milli>(std::chrono::steady_clock::now() - start).count();
}

bool Scan3dPipeline::range_image(const interfaces::Scan3dData& scan, double sx, double sy, double sz, double resolution,
                                 interfaces::Scan3dRangeImage& out, std::string& error) {
  const uint32_t n = std::min(scan.point_count, interfaces::kScan3dMaxPoints);
  if (n == 0) {
    error = "the scan has no points";
    return false;
  }
  // PCL first renders the whole sphere at this resolution, then crops it: below 0.2
  // degrees that is millions of pixels (seconds, hundreds of MB) for any scan.
  if (!(resolution >= kMinRangeImageResolution && resolution < 1.0)) {
    error = "angular resolution must be between 0.2 and 57 degrees";
    return false;
  }
  // The cropped image's size, from the points' directions: refuse before PCL works.
  double az_min = 10, az_max = -10, el_min = 10, el_max = -10;
  for (uint32_t i = 0; i < n; ++i) {
    const double dx = scan.x[i] - sx, dy = scan.y[i] - sy, dz = scan.z[i] - sz;
    const double az = std::atan2(dy, dx), el = std::atan2(dz, std::hypot(dx, dy));
    az_min = std::min(az_min, az);
    az_max = std::max(az_max, az);
    el_min = std::min(el_min, el);
    el_max = std::max(el_max, el);
  }
  const double est = ((az_max - az_min) / resolution + 1.0) * ((el_max - el_min) / resolution + 1.0);
  if (est > 1.05 * interfaces::kScan3dRangeImageMaxPixels) {
    error = "the range image (about " + std::to_string(static_cast<uint64_t>(est)) + " pixels) exceeds " +
            std::to_string(interfaces::kScan3dRangeImageMaxPixels) + " pixels: ask for a coarser resolution";
    return false;
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.resize(n);
  for (uint32_t i = 0; i < n; ++i) cloud[i] = pcl::PointXYZ(scan.x[i], scan.y[i], scan.z[i]);
  const Eigen::Affine3f pose(
      Eigen::Translation3f(static_cast<float>(sx), static_cast<float>(sy), static_cast<float>(sz)));
  pcl::RangeImage image;
  image.createFromPointCloud(cloud, static_cast<float>(resolution), pcl::deg2rad(360.0F), pcl::deg2rad(180.0F), pose,
                             pcl::RangeImage::LASER_FRAME, 0.0F, 0.0F, 0);
  const uint32_t w = image.width, h = image.height;
  if (w == 0 || h == 0) {
    error = "the range image is empty";
    return false;
  }
  if (static_cast<uint64_t>(w) * h > interfaces::kScan3dRangeImageMaxPixels) {
    error = "the range image (" + std::to_string(w) + " x " + std::to_string(h) + ") exceeds " +
            std::to_string(interfaces::kScan3dRangeImageMaxPixels) + " pixels: ask for a coarser resolution";
    return false;
  }
  // Directions of the corners, measured rather than assumed from PCL's image
  // conventions: the image is flipped where needed so that column 0 is the left
  // (largest azimuth) and row 0 the top.
  const auto direction = [&](int px, int py, double& azimuth, double& elevation) {
    Eigen::Vector3f p;
    image.calculate3DPoint(static_cast<float>(px), static_cast<float>(py), 1.0F, p);
    const double dx = p.x() - sx, dy = p.y() - sy, dz = p.z() - sz;
    azimuth = std::atan2(dy, dx);
    elevation = std::atan2(dz, std::hypot(dx, dy));
  };
  double az0 = 0, el0 = 0, az1 = 0, el1 = 0;
  direction(0, 0, az0, el0);
  direction(0, static_cast<int>(h) - 1, az1, el1);
  // Azimuths wrap at +-pi: compare the step from column 0 to column 1 instead.
  double az_next = az0, el_dummy = 0;
  if (w > 1) direction(1, 0, az_next, el_dummy);
  const double step = std::remainder(az_next - az0, 2.0 * M_PI);
  const bool flip_x = w > 1 && step > 0.0;  // column 0 should have the largest azimuth
  const bool flip_y = el0 < el1;            // row 0 should be the highest
  for (uint32_t row = 0; row < h; ++row) {
    for (uint32_t col = 0; col < w; ++col) {
      const float r = image.getPoint(static_cast<int>(col), static_cast<int>(row)).range;
      const uint32_t orow = flip_y ? h - 1 - row : row;
      const uint32_t ocol = flip_x ? w - 1 - col : col;
      out.range[orow * w + ocol] = std::isfinite(r) && r > 0.0F ? r : 0.0F;
    }
  }
  // The output's corner (0, 0) is the input pixel it was copied from.
  double left = 0, top = 0;
  direction(flip_x ? static_cast<int>(w) - 1 : 0, flip_y ? static_cast<int>(h) - 1 : 0, left, top);
  out.width = w;
  out.height = h;
  out.angular_resolution = static_cast<float>(resolution);
  out.angle_left = static_cast<float>(left);
  out.angle_top = static_cast<float>(top);
  return true;
}

}  // namespace rack::scan3d
