// Where a 2-D ladar's beam points when the ladar turns on a servo drive: RACK's roll,
// pitch and yaw scan modes, shared by Scan3D (assembly) and LadarSim (rendering a
// 3-D world), so that both agree on one definition.
//
// The ladar's own frame: beam bearing b counter-clockwise from its axis. The drive
// turns the ladar about an axis through the ladar's centre, which sits at
// (mount_x, mount_y, mount_z) in the robot frame (x forward, y left, z up); drive
// angle theta:
//   pitch: scan plane horizontal at theta = 0 (the ladar looks forward); the drive
//          tilts it about the y axis, positive theta lifts the forward beams:
//          (r cos b cos theta, r sin b, r cos b sin theta)
//   roll:  scan plane horizontal at theta = 0; the drive turns it about the x axis,
//          positive theta lifts the beams on the left:
//          (r cos b, r sin b cos theta, r sin b sin theta)
//   yaw:   scan plane vertical (the ladar mounted on its side: bearing b counts
//          upwards from the forward axis); the drive turns that plane about the z
//          axis, positive theta to the left:
//          (r cos b cos theta, r cos b sin theta, r sin b)
//
// Real-time contract: RT-safe (pure functions).
#pragma once

#include <cmath>
#include <cstdint>

// The scan modes (RACK's), as Scan3dData's `mode` carries them (namespace
// rack::interfaces, where they were declared before Scan3D's types moved into its folder).
namespace rack::interfaces {

// How the scan was made (RACK's scan modes). The drive angle turns the ladar's scan
// plane about the robot's x axis (roll), y axis (pitch) or z axis (yaw): exactly as
// above and in scan3d_direction() below.
inline constexpr uint8_t kScan3dModeRoll = 0;
inline constexpr uint8_t kScan3dModePitch = 1;
inline constexpr uint8_t kScan3dModeYaw = 2;
inline constexpr uint8_t kScan3dModeFile = 3;  // played from PCD files

}  // namespace rack::interfaces

namespace rack::components {

struct Vec3 {
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;
};

struct Scan3dMount {
  uint8_t mode = interfaces::kScan3dModePitch;  // kScan3dModeRoll / Pitch / Yaw
  double x = 0.0;                               // m, the ladar's centre in the robot frame
  double y = 0.0;
  double z = 0.0;
};

// The direction (unit vector, robot frame) of the beam at `bearing` when the drive is
// at `theta`.
[[nodiscard]] inline Vec3 scan3d_direction(uint8_t mode, double theta, double bearing) noexcept {
  const double cb = std::cos(bearing), sb = std::sin(bearing);
  const double ct = std::cos(theta), st = std::sin(theta);
  switch (mode) {
    case interfaces::kScan3dModeRoll: return Vec3{cb, sb * ct, sb * st};
    case interfaces::kScan3dModeYaw: return Vec3{cb * ct, cb * st, sb};
    default: return Vec3{cb * ct, sb, cb * st};  // pitch
  }
}

// The point (robot frame) a beam with `range` hit.
[[nodiscard]] inline Vec3 scan3d_point(const Scan3dMount& m, double theta, double bearing, double range) noexcept {
  const Vec3 d = scan3d_direction(m.mode, theta, bearing);
  return Vec3{m.x + range * d.x, m.y + range * d.y, m.z + range * d.z};
}

}  // namespace rack::components
