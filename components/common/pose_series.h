// A short history of the robot's 2-D pose (x, y, heading) with timestamps, from an
// Odometry or Position stream, interpolated at any time inside it: Scan3D needs the
// robot's pose at the moment of each laser beam to undo the robot's motion during a
// sweep (time_series.h is the same for a scalar).
//
// No extrapolation: a pose after the newest sample is unknown (a moving robot is not
// where it was), so a caller waits for the next sample.
//
// Real-time contract: RT-safe (fixed capacity inside the object, no allocation); one
// thread.
#pragma once

#include <cstddef>
#include <cstdint>

#include "common/pose2d.h"
#include "common/time_series.h"

namespace rack::components {

template <std::size_t N = 256>
class PoseSeries : public StampedSeries<Pose2d, N> {
 public:
  // The pose at time t: x and y linear between the two samples around t, the heading
  // along the shorter way round. kTooOld before the oldest sample, kTooNew after the
  // newest, kEmpty without samples. The caller checks that what it pushes is finite.
  [[nodiscard]] SeriesLookup pose_at(int64_t t, Pose2d& out) const noexcept {
    return this->lookup(t, 0, out, [](const Pose2d& a, const Pose2d& b, double f) {
      return Pose2d{a.x + f * (b.x - a.x), a.y + f * (b.y - a.y),
                    normalize_angle(a.phi + f * normalize_angle(b.phi - a.phi))};
    });
  }
};

}  // namespace rack::components
