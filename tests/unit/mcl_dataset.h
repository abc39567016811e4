// The real-data localisation sets of bench/data/carmen/ (see the README there): a
// CARMEN log (gzip) with one ODOM, TRUEPOS and FLASER line per scan, read into the
// same steps as the simulated robot's (mcl_sim.h): odometry pose, reference pose,
// scan (raw beams for MRPT's CObservation2DRangeScan, robot-frame points of the
// echoes for rack's filter).
//
// Test and bench code; nothing here is RT-safe. Malformed input is reported in `error`
// with the line number (the committed files are the only input).
#pragma once

#include <zlib.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "mcl_sim.h"

namespace rack::test {

struct DatasetStep {
  SimPose odometry, truth;
  SimScan scan;
  double time = 0.0;  // s, the log's own time
};

struct Dataset {
  std::string name;
  std::vector<DatasetStep> steps;
  std::string error;  // empty when read
};

// Reads NAME.log.gz (written by bench/data/carmen/make_datasets.py). `decimate` keeps
// every n-th scan (1: all).
inline Dataset load_dataset(const std::string& path, std::size_t decimate = 1) {
  Dataset d;
  d.name = path;
  gzFile f = gzopen(path.c_str(), "rb");
  if (f == nullptr) {
    d.error = path + ": cannot open";
    return d;
  }
  std::string text;
  char buf[1 << 16];
  for (int n = 0; (n = gzread(f, buf, sizeof buf)) > 0;) text.append(buf, static_cast<std::size_t>(n));
  gzclose(f);
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  float max_range = 81.9F;
  SimPose truth, odo;
  bool have_truth = false;
  std::size_t scan_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream w(line);
    std::string kind;
    if (!(w >> kind) || kind[0] == '#') continue;
    if (kind == "PARAM") {
      std::string key;
      w >> key;
      if (key == "flaser_max_range") w >> max_range;
    } else if (kind == "TRUEPOS") {
      w >> truth.x >> truth.y >> truth.phi;
      have_truth = static_cast<bool>(w);
    } else if (kind == "FLASER") {
      std::size_t n = 0;
      w >> n;
      if (!w || n < 2 || n > 10000) {
        d.error = path + ":" + std::to_string(line_no) + ": FLASER: bad beam count";
        return d;
      }
      DatasetStep s;
      s.scan.start_angle = static_cast<float>(-std::numbers::pi / 2);
      s.scan.step = static_cast<float>(std::numbers::pi / static_cast<double>(n - 1));
      s.scan.max_range = max_range;
      for (std::size_t i = 0; i < n; ++i) {
        float r = 0;
        w >> r;
        const bool echo = r > 0.0F && r < max_range - 0.01F;
        s.scan.ranges.push_back(echo ? r : max_range);
        s.scan.valid.push_back(echo ? 1 : 0);
        if (echo) {
          const double a = s.scan.start_angle + static_cast<double>(i) * double{s.scan.step};
          s.scan.xs.push_back(static_cast<float>(r * std::cos(a)));
          s.scan.ys.push_back(static_cast<float>(r * std::sin(a)));
        }
      }
      double ox = 0, oy = 0, oth = 0;
      w >> odo.x >> odo.y >> odo.phi >> ox >> oy >> oth >> s.time;
      if (!w || !have_truth) {
        d.error = path + ":" + std::to_string(line_no) + ": FLASER: missing fields or no TRUEPOS before it";
        return d;
      }
      s.odometry = odo;
      s.truth = truth;
      have_truth = false;
      if (scan_no++ % decimate == 0) d.steps.push_back(std::move(s));
    }
  }
  if (d.steps.empty()) d.error = path + ": no scans";
  return d;
}

}  // namespace rack::test
