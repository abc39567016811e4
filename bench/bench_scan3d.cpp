// bench_scan3d: Scan3D's processing time per 3-D scan (Scan3dPipeline::process, what
// the component's data task runs for every sweep: copy into PCL, voxel grid,
// statistical outlier removal, RANSAC ground plane, typing, copy into Scan3dData)
// beside the same PCL pipeline called directly on a pcl::PointCloud (the reference),
// on the same clouds, interleaved in the same run (A B, B A, ...), so that load from
// elsewhere falls on both sides alike.
//
//   bench_scan3d [--scans N] [--points N] [--voxel M] [--json FILE]
//
// Clouds: a synthetic room per scan (an 8 m floor with 1 cm noise, boxes at random
// places, a ceiling, stray points), about --points points each, different per scan.
// Prints percentiles of both, wall time and the thread's CPU time (the CPU time is
// what to compare on a shared machine: preemption by other work does not count),
// and the ratios ours/reference. --json FILE writes them (FILE "-": stdout).
// Exit code 1 when the two sides' results differ (points kept, ground points).
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bench_common.h"
#include "scan3d/scan3d_types.h"
#include "rack/interfaces/robot.h"
#include "rack/scan3d/scan3d_pipeline.h"

namespace {

int64_t thread_cpu_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct Cloud {
  std::vector<float> x, y, z, i;
};

Cloud make_room(uint32_t seed, uint32_t points) {
  Cloud c;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> u(-3.5, 3.5);
  const auto add = [&](double x, double y, double z) {
    c.x.push_back(static_cast<float>(x));
    c.y.push_back(static_cast<float>(y));
    c.z.push_back(static_cast<float>(z));
    c.i.push_back(1.0F);
  };
  // 60 % floor, 20 % ceiling, 20 % boxes.
  const double floor_step = 8.0 / std::sqrt(0.6 * points);
  for (double x = -4; x <= 4; x += floor_step) {
    for (double y = -4; y <= 4; y += floor_step) add(x, y, noise(rng));
  }
  const double ceil_step = 8.0 / std::sqrt(0.2 * points);
  for (double x = -4; x <= 4; x += ceil_step) {
    for (double y = -4; y <= 4; y += ceil_step) add(x, y, 2.5 + noise(rng));
  }
  const auto box_points = static_cast<uint32_t>(0.2 * points);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int b = 0; b < 5; ++b) {
    const double cx = u(rng), cy = u(rng), s = 0.3 + 0.5 * unit(rng), h = 0.4 + unit(rng);
    for (uint32_t k = 0; k < box_points / 5; ++k) {  // random points on the box's sides
      const double side = unit(rng) * 4, t = unit(rng) * s - s / 2, z = unit(rng) * h;
      const int si = static_cast<int>(side);
      add(cx + (si == 0 ? -s / 2 : si == 1 ? s / 2 : t), cy + (si == 2 ? -s / 2 : si == 3 ? s / 2 : t), z);
    }
  }
  for (int k = 0; k < 50; ++k) add(u(rng), u(rng), 0.5 + 1.5 * unit(rng));  // strays
  return c;
}

// The reference: PCL called directly, the same steps and parameters.
struct Reference {
  using PclCloud = pcl::PointCloud<pcl::PointXYZI>;
  PclCloud::Ptr in{new PclCloud}, voxels{new PclCloud}, cleaned{new PclCloud};
  std::vector<uint8_t> type;
  uint32_t ground = 0;

  void run(const Cloud& c, const rack::scan3d::PipelineOptions& o) {
    in->resize(c.x.size());
    for (std::size_t k = 0; k < c.x.size(); ++k) {
      (*in)[k].x = c.x[k];
      (*in)[k].y = c.y[k];
      (*in)[k].z = c.z[k];
      (*in)[k].intensity = c.i[k];
    }
    pcl::VoxelGrid<pcl::PointXYZI> grid;
    grid.setInputCloud(in);
    const auto leaf = static_cast<float>(o.voxel_size);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.filter(*voxels);
    pcl::StatisticalOutlierRemoval<pcl::PointXYZI> sor;
    sor.setInputCloud(voxels);
    sor.setMeanK(o.outlier_neighbours);
    sor.setStddevMulThresh(o.outlier_std);
    sor.filter(*cleaned);
    pcl::IndicesPtr candidates(new pcl::Indices);
    for (std::size_t k = 0; k < cleaned->size(); ++k) {
      if (std::fabs((*cleaned)[k].z) <= o.ground_max_height) candidates->push_back(static_cast<pcl::index_t>(k));
    }
    pcl::SACSegmentation<pcl::PointXYZI> seg;
    seg.setOptimizeCoefficients(true);
    seg.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
    seg.setMethodType(pcl::SAC_RANSAC);
    seg.setAxis(Eigen::Vector3f(0.0F, 0.0F, 1.0F));
    seg.setEpsAngle(o.ground_max_tilt);
    seg.setDistanceThreshold(o.ground_tolerance);
    seg.setMaxIterations(o.ransac_iterations);
    seg.setInputCloud(cleaned);
    seg.setIndices(candidates);
    pcl::PointIndices inliers;
    pcl::ModelCoefficients coeff;
    seg.segment(inliers, coeff);
    type.assign(cleaned->size(), rack::interfaces::kScanPointNormal);
    ground = 0;
    if (coeff.values.size() == 4) {
      float a = coeff.values[0], b = coeff.values[1], cc = coeff.values[2], d = coeff.values[3];
      const float s = (cc < 0 ? -1.0F : 1.0F) / std::sqrt(a * a + b * b + cc * cc);
      a *= s;
      b *= s;
      cc *= s;
      d *= s;
      for (std::size_t k = 0; k < cleaned->size(); ++k) {
        const auto& p = (*cleaned)[k];
        const float h = a * p.x + b * p.y + cc * p.z + d;
        if (std::fabs(h) <= o.ground_tolerance) {
          type[k] = rack::interfaces::kScanPointGround;
          ++ground;
        } else if (o.ceiling_height > 0 && h > o.ceiling_height) {
          type[k] = rack::interfaces::kScanPointCeiling;
        } else {
          type[k] = rack::interfaces::kScanPointObstacle;
        }
      }
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  uint32_t scans = 40, points = 60000;
  double voxel = 0.08;  // leaves ~20 000 points: below max_points, so both sides keep the same points
  std::string json_path;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    const auto next = [&]() -> const char* {
      if (k + 1 >= argc) {
        std::fprintf(stderr, "bench_scan3d: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++k];
    };
    if (a == "--scans") scans = static_cast<uint32_t>(std::atoi(next()));
    else if (a == "--points") points = static_cast<uint32_t>(std::atoi(next()));
    else if (a == "--voxel") voxel = std::atof(next());
    else if (a == "--json") json_path = next();
    else {
      std::fprintf(stderr,
                   "usage: bench_scan3d [--scans N] [--points N] [--voxel M] [--json FILE]\n"
                   "Scan3D's per-scan processing (Scan3dPipeline) beside the same PCL pipeline called directly.\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (scans < 2 || points < 1000) {
    std::fprintf(stderr, "bench_scan3d: need --scans >= 2 and --points >= 1000\n");
    return 2;
  }
  rack::scan3d::PipelineOptions o;
  o.voxel_size = voxel;
  o.ceiling_height = 2.0;
  rack::scan3d::Scan3dPipeline ours;
  Reference reference;
  auto out = std::make_unique<rack::interfaces::Scan3dData>();
  std::vector<int64_t> t_ours, t_ref, c_ours, c_ref;  // wall time, and the thread's CPU time
  uint64_t mismatched = 0, raw_total = 0, kept_total = 0;
  // One warm-up round each (first-touch allocation of the reused clouds).
  {
    const Cloud c = make_room(12345, points);
    ours.process(c.x.data(), c.y.data(), c.z.data(), c.i.data(), c.x.size(), o, *out);
    reference.run(c, o);
  }
  for (uint32_t s = 0; s < scans; ++s) {
    const Cloud c = make_room(s + 1, points);
    raw_total += c.x.size();
    const auto time_ours = [&] {
      const int64_t c0 = thread_cpu_ns();
      const auto t0 = std::chrono::steady_clock::now();
      ours.process(c.x.data(), c.y.data(), c.z.data(), c.i.data(), c.x.size(), o, *out);
      t_ours.push_back(
          std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
      c_ours.push_back(thread_cpu_ns() - c0);
    };
    const auto time_ref = [&] {
      const int64_t c0 = thread_cpu_ns();
      const auto t0 = std::chrono::steady_clock::now();
      reference.run(c, o);
      t_ref.push_back(
          std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
      c_ref.push_back(thread_cpu_ns() - c0);
    };
    if (s % 2 == 0) {
      time_ours();
      time_ref();
    } else {
      time_ref();
      time_ours();
    }
    // Same work: the same points kept and the same ground count.
    kept_total += out->point_count;
    if (out->point_count != reference.type.size() || out->ground_points != reference.ground) ++mismatched;
  }
  const auto po = rack::bench::percentiles_of(t_ours);
  const auto pr = rack::bench::percentiles_of(t_ref);
  const auto cpo = rack::bench::percentiles_of(c_ours);
  const auto cpr = rack::bench::percentiles_of(c_ref);
  const auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  std::printf("bench_scan3d: %u scans of ~%llu points (voxel %.3f m -> ~%llu points), %s\n", scans,
              static_cast<unsigned long long>(raw_total / scans), voxel,
              static_cast<unsigned long long>(kept_total / scans), rack::bench::kernel_string().c_str());
  std::printf("  %-28s p50 %8.2f ms  p90 %8.2f ms  p99 %8.2f ms  max %8.2f ms\n", "Scan3dPipeline::process",
              po.p50_ns / 1e6, po.p90_ns / 1e6, po.p99_ns / 1e6, po.max_ns / 1e6);
  std::printf("  %-28s p50 %8.2f ms  p90 %8.2f ms  p99 %8.2f ms  max %8.2f ms\n", "PCL directly (reference)",
              pr.p50_ns / 1e6, pr.p90_ns / 1e6, pr.p99_ns / 1e6, pr.max_ns / 1e6);
  std::printf("  ratio ours/reference (wall): p50 %.3f  p90 %.3f  p99 %.3f\n", ratio(po.p50_ns, pr.p50_ns),
              ratio(po.p90_ns, pr.p90_ns), ratio(po.p99_ns, pr.p99_ns));
  std::printf(
      "  thread CPU time: ours p50 %.2f ms p90 %.2f ms, reference p50 %.2f ms p90 %.2f ms; ratio p50 %.3f p90 %.3f\n",
      cpo.p50_ns / 1e6, cpo.p90_ns / 1e6, cpr.p50_ns / 1e6, cpr.p90_ns / 1e6, ratio(cpo.p50_ns, cpr.p50_ns),
      ratio(cpo.p90_ns, cpr.p90_ns));
  std::printf("  scans whose results differ (points kept, ground points): %llu\n",
              static_cast<unsigned long long>(mismatched));
  std::string json = "{\"benchmark\": \"scan3d\", \"machine\": " + rack::bench::json_machine() +
                     ", \"scans\": " + std::to_string(scans) +
                     ", \"points_per_scan\": " + std::to_string(raw_total / scans) +
                     ", \"points_after_processing\": " + std::to_string(kept_total / scans) +
                     ", \"voxel_m\": " + rack::bench::json_number(voxel) +
                     ", \"ours\": " + rack::bench::json_percentiles(po) +
                     ", \"reference\": " + rack::bench::json_percentiles(pr) +
                     ", \"ours_cpu\": " + rack::bench::json_percentiles(cpo) +
                     ", \"reference_cpu\": " + rack::bench::json_percentiles(cpr) +
                     ", \"ratio_cpu\": {\"p50\": " + rack::bench::json_number(ratio(cpo.p50_ns, cpr.p50_ns)) +
                     ", \"p90\": " + rack::bench::json_number(ratio(cpo.p90_ns, cpr.p90_ns)) + "}" +
                     ", \"ratio\": {\"p50\": " + rack::bench::json_number(ratio(po.p50_ns, pr.p50_ns)) +
                     ", \"p90\": " + rack::bench::json_number(ratio(po.p90_ns, pr.p90_ns)) +
                     ", \"p99\": " + rack::bench::json_number(ratio(po.p99_ns, pr.p99_ns)) +
                     "}, \"results_differ\": " + std::to_string(mismatched) + "}\n";
  if (!json_path.empty()) {
    if (json_path == "-") {
      std::fputs(json.c_str(), stdout);
    } else if (!rack::bench::write_file(json_path, json)) {
      std::fprintf(stderr, "bench_scan3d: cannot write %s\n", json_path.c_str());
      return 1;
    }
  }
  return mismatched == 0 ? 0 : 1;
}
