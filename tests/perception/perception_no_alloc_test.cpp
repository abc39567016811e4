// No allocation on the perception code that runs in real-time tasks: the laser
// tracker (Scan2D's data task with dynamic_objects, ObjRecogLaser's) and the 3-D
// assembly (Scan3dAssembler: drive samples and ladar scans, with and without motion
// compensation from odometry poses). The counting allocator
// of tests/unit/counting_allocator.h counts on this thread only, around the measured
// calls, after the objects were built (their constructors may allocate: init()).
// Alone in its binary because the replacement is global.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "../unit/test_support.h"

namespace {
thread_local bool g_counting = false;
thread_local uint64_t g_allocations = 0;
}  // namespace

void rack_test_note_allocation(rack::rt::modeswitch::detail::HeapCall, std::size_t) noexcept {
  if (g_counting) ++g_allocations;
}
void rack_test_note_free() noexcept {}

#include "../unit/counting_allocator.h"

#include "common/pose2d.h"
#include "obj_recog/laser_tracker.h"
#include "obj_recog/obj_recog_laser.h"
#include "obj_recog/obj_recog_types.h"
#include "rack/scan3d/scan3d_assembler.h"

namespace rack::test {
namespace {

class Counting {
 public:
  Counting() {
    g_allocations = 0;
    g_counting = true;
  }
  ~Counting() { g_counting = false; }
  uint64_t stop() {
    g_counting = false;
    return g_allocations;
  }
};

TEST(PerceptionNoAllocTest, TheCounterCounts) {
  Counting c;
  auto p = std::make_unique<int>(1);
  EXPECT_EQ(c.stop(), 1U);
}

TEST(PerceptionNoAllocTest, LaserTrackerAndObjectList) {
  auto tracker = std::make_unique<components::LaserTracker>();
  auto scan = std::make_unique<interfaces::Scan2dData>();
  auto out = std::make_unique<interfaces::ObjRecogData>();
  Counting c;
  for (int k = 0; k < 50; ++k) {
    // Three small objects (one moving) and a wall of points.
    uint32_t n = 0;
    for (int o = 0; o < 3; ++o) {
      for (int p = 0; p < 6; ++p) {
        scan->x[n] = static_cast<float>(2.0 + o + (o == 0 ? 0.05 * k : 0.0));
        scan->y[n] = static_cast<float>(-1.0 + 0.03 * p + o);
        scan->type[n++] = interfaces::kScanPointNormal;
      }
    }
    for (int p = 0; p < 200; ++p) {
      scan->x[n] = static_cast<float>(-3.0 + 0.03 * p);
      scan->y[n] = 4.0F;
      scan->type[n++] = interfaces::kScanPointNormal;
    }
    scan->point_count = n;
    tracker->update(*scan, components::Pose2d{0.01 * k, 0.0, 0.0}, k * 100'000'000LL);
    (void)tracker->mark_dynamic(*scan);
    components::ObjRecogLaser::fill(*tracker, *out);
  }
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_EQ(out->object_count, 3U);
}

// A 2-D scan of 361 beams, every one with an echo (made before counting starts).
std::unique_ptr<interfaces::LadarData> wall_scan() {
  auto scan = std::make_unique<interfaces::LadarData>();
  scan->beam_count = 361;
  scan->start_angle = -1.5F;
  scan->angle_step = 0.01F;
  scan->max_range = 10.0F;
  scan->duration_ns = 20'000'000;
  for (uint32_t b = 0; b < scan->beam_count; ++b) scan->range[b] = 2.0F + 0.001F * static_cast<float>(b);
  return scan;
}

TEST(PerceptionNoAllocTest, Scan3dAssembly) {
  auto a = std::make_unique<scan3d::Scan3dAssembler>(100000);
  auto scan = wall_scan();
  Counting c;
  a->reset();
  for (int k = 0; k < 200; ++k) a->add_drive_sample(k * 10'000'000LL, -0.5 + 0.005 * k);
  uint32_t added = 0;
  for (int k = 0; k < 40; ++k) added += a->add_scan(*scan, k * 40'000'000LL) == scan3d::AddStatus::kAdded;
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_EQ(added, 40U);
  EXPECT_EQ(a->size(), 40U * 361U);
}

// The same with motion compensation: poses into the ring (more than it holds, so it
// wraps), each beam moved by its interpolated pose, the sweep into the end frame.
TEST(PerceptionNoAllocTest, Scan3dAssemblyWithMotionCompensation) {
  auto a = std::make_unique<scan3d::Scan3dAssembler>(100000);
  scan3d::AssemblerConfig cfg;
  cfg.compensate_motion = true;
  a->set_config(cfg);
  auto scan = wall_scan();
  Counting c;
  a->reset();
  for (int k = 0; k < 600; ++k) {
    a->add_drive_sample(k * 10'000'000LL, -0.5 + 0.002 * k);
    if (k % 2 == 0) (void)a->add_pose(k * 10'000'000LL, components::Pose2d{0.005 * k, 0.001 * k, 0.0005 * k});
  }
  uint32_t added = 0;
  for (int k = 100; k < 140; ++k) added += a->add_scan(*scan, k * 40'000'000LL) == scan3d::AddStatus::kAdded;
  const bool moved = a->to_end_frame();
  EXPECT_EQ(c.stop(), 0U);
  EXPECT_EQ(added, 40U);
  EXPECT_TRUE(moved);
  EXPECT_EQ(a->size(), 40U * 361U);
}

}  // namespace
}  // namespace rack::test
