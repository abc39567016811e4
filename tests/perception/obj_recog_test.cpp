// ObjectRecognition: ArUco markers rendered at known poses into a synthetic camera
// image (the pose comes back within a stated tolerance, raw and JPEG), wrong images
// (a clear error, nothing detected), the HOG path, velocities from consecutive images,
// and the laser tracker: a moving cluster's velocity, static objects and walls, the
// robot's own motion compensated, DYN_OBSTACLE marks for Scan2D.
#include <gtest/gtest.h>

#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "obj_recog/camera_detector.h"
#include "obj_recog/laser_tracker.h"
#include "obj_recog/obj_recog_camera.h"
#include "obj_recog/obj_recog_laser.h"
#include "rack/components/class_ids.h"
#include "obj_recog/obj_recog_types.h"
#include "rack/interfaces/devices.h"
#include "../unit/test_support.h"
#include "wrong_type_producer.h"

namespace rack::test {
namespace {

using components::CameraDetector;
using components::CameraIntrinsics;
using interfaces::CameraData;
using interfaces::ObjRecogData;

constexpr int kWidth = 640, kHeight = 480;
constexpr double kMarker = 0.15;  // m

CameraIntrinsics intrinsics() {
  CameraIntrinsics k;
  k.valid = true;
  k.width = kWidth;
  k.height = kHeight;
  k.fx = k.fy = 600.0;
  k.cx = 320.0;
  k.cy = 240.0;
  return k;
}

cv::Matx33d rot_x(double a) { return {1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a)}; }
cv::Matx33d rot_y(double a) { return {std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a)}; }
cv::Matx33d rot_z(double a) { return {std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1}; }

struct MarkerPose {
  int id;
  cv::Vec3d t;    // m, camera frame
  cv::Matx33d r;  // marker frame (x right, y up, z out of the marker) in the camera frame
};

// Renders markers (with their white quiet zone) at the poses, by projecting their
// corners with the pinhole model and warping the marker image there.
cv::Mat render(const std::vector<MarkerPose>& markers) {
  cv::Mat image(kHeight, kWidth, CV_8UC1, cv::Scalar(170));
  const auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  const CameraIntrinsics k = intrinsics();
  const cv::Matx33d camera(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  for (const MarkerPose& m : markers) {
    cv::Mat marker;
    cv::aruco::drawMarker(dict, m.id, 300, marker, 1);
    cv::Mat canvas(500, 500, CV_8UC1, cv::Scalar(255));
    marker.copyTo(canvas(cv::Rect(100, 100, 300, 300)));
    // The canvas spans 5/3 of the marker's side; its corners in the marker frame.
    const double h = kMarker / 2 * 500.0 / 300.0;
    const std::vector<cv::Point3d> corners = {{-h, h, 0}, {h, h, 0}, {h, -h, 0}, {-h, -h, 0}};
    cv::Vec3d rvec;
    cv::Rodrigues(cv::Mat(m.r), rvec);
    std::vector<cv::Point2d> projected;
    cv::projectPoints(corners, rvec, m.t, camera, cv::noArray(), projected);
    const std::vector<cv::Point2f> src = {{0, 0}, {500, 0}, {500, 500}, {0, 500}};
    const std::vector<cv::Point2f> dst(projected.begin(), projected.end());
    cv::warpPerspective(canvas, image, cv::getPerspectiveTransform(src, dst), image.size(), cv::INTER_LINEAR,
                        cv::BORDER_TRANSPARENT);
  }
  return image;
}

std::unique_ptr<CameraData> frame_of(const cv::Mat& gray, uint8_t format) {
  auto f = std::make_unique<CameraData>();
  f->width = static_cast<uint32_t>(gray.cols);
  f->height = static_cast<uint32_t>(gray.rows);
  f->format = format;
  if (format == interfaces::kCameraMono8) {
    std::memcpy(f->data, gray.data, gray.total());
    f->bytes = static_cast<uint32_t>(gray.total());
  } else if (format == interfaces::kCameraRgb8) {
    cv::Mat rgb;
    cv::cvtColor(gray, rgb, cv::COLOR_GRAY2RGB);
    std::memcpy(f->data, rgb.data, rgb.total() * 3);
    f->bytes = static_cast<uint32_t>(rgb.total() * 3);
  } else {
    std::vector<uint8_t> jpeg;
    cv::imencode(".jpg", gray, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95});
    std::memcpy(f->data, jpeg.data(), jpeg.size());
    f->bytes = static_cast<uint32_t>(jpeg.size());
  }
  return f;
}

// Angle of the rotation between two rotation matrices.
double angle_between(const cv::Matx33d& a, const cv::Matx33d& b) {
  const cv::Matx33d d = a.t() * b;
  return std::acos(std::clamp((d(0, 0) + d(1, 1) + d(2, 2) - 1.0) / 2.0, -1.0, 1.0));
}

// Stated tolerance: position within 1 cm + 1 % of the distance, orientation within 3 degrees.
class ArucoPoseTest : public ::testing::TestWithParam<uint8_t> {};

TEST_P(ArucoPoseTest, MarkersAtKnownPosesComeBackWithTheirPose) {
  const std::vector<MarkerPose> markers = {
      {7, {0.10, -0.05, 1.2}, rot_x(M_PI) * rot_y(0.35) * rot_x(0.15)},  // facing the camera, turned 20 deg
      {3, {-0.35, 0.12, 1.8}, rot_x(M_PI) * rot_y(-0.25) * rot_z(0.6)},  // farther, rotated in its plane
  };
  const cv::Mat image = render(markers);
  const auto frame = frame_of(image, GetParam());
  components::DetectorOptions o;
  o.marker_length = kMarker;
  CameraDetector detector(o);
  auto out = std::make_unique<ObjRecogData>();
  std::string error;
  ASSERT_TRUE(detector.detect(*frame, intrinsics(), *out, error)) << error;
  ASSERT_EQ(out->object_count, markers.size());
  EXPECT_EQ(out->frame, interfaces::kObjFrameCamera);
  for (const MarkerPose& m : markers) {
    bool found = false;
    for (uint32_t i = 0; i < out->object_count; ++i) {
      if (out->id[i] != static_cast<uint32_t>(m.id)) continue;
      found = true;
      EXPECT_EQ(out->type[i], interfaces::kObjTypeFiducial);
      const double distance = cv::norm(m.t);
      const double err = std::hypot(std::hypot(out->x[i] - m.t[0], out->y[i] - m.t[1]), out->z[i] - m.t[2]);
      EXPECT_LT(err, 0.01 + 0.01 * distance)
          << "marker " << m.id << " at (" << out->x[i] << ", " << out->y[i] << ", " << out->z[i] << ")";
      const cv::Matx33d r = rot_z(out->yaw[i]) * rot_y(out->pitch[i]) * rot_x(out->roll[i]);
      EXPECT_LT(angle_between(r, m.r), 3.0 * M_PI / 180.0) << "marker " << m.id;
      EXPECT_FLOAT_EQ(out->size_x[i], static_cast<float>(kMarker));
      EXPECT_GT(out->image_width[i], 30);
      EXPECT_GT(out->image_height[i], 30);
    }
    EXPECT_TRUE(found) << "marker " << m.id << " not found";
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, ArucoPoseTest,
                         ::testing::Values(interfaces::kCameraMono8, interfaces::kCameraRgb8, interfaces::kCameraJpeg),
                         [](const ::testing::TestParamInfo<uint8_t>& i) {
                           return std::string(i.param == interfaces::kCameraMono8  ? "Mono8"
                                              : i.param == interfaces::kCameraRgb8 ? "Rgb8"
                                                                                   : "Jpeg");
                         });

TEST(CameraDetectorTest, ScalesIntrinsicsToTheFrameAndRefusesAnotherAspect) {
  const cv::Mat image = render({{5, {0.0, 0.0, 1.0}, rot_x(M_PI)}});
  cv::Mat half;
  cv::resize(image, half, cv::Size(kWidth / 2, kHeight / 2), 0, 0, cv::INTER_AREA);
  components::DetectorOptions o;
  o.marker_length = kMarker;
  CameraDetector detector(o);
  auto out = std::make_unique<ObjRecogData>();
  std::string error;
  ASSERT_TRUE(detector.detect(*frame_of(half, interfaces::kCameraMono8), intrinsics(), *out, error)) << error;
  ASSERT_EQ(out->object_count, 1U);
  EXPECT_NEAR(out->z[0], 1.0, 0.03);  // the same pose from the half-size image
  cv::Mat wide;
  cv::resize(image, wide, cv::Size(kWidth, kHeight / 2));
  out->object_count = 77;
  EXPECT_FALSE(detector.detect(*frame_of(wide, interfaces::kCameraMono8), intrinsics(), *out, error));
  EXPECT_NE(error.find("aspect ratio"), std::string::npos) << error;
  EXPECT_EQ(out->object_count, 77U) << "a refused frame leaves the output alone";
}

TEST(CameraDetectorTest, WrongImagesGetAClearError) {
  components::DetectorOptions o;
  CameraDetector detector(o);
  auto out = std::make_unique<ObjRecogData>();
  auto f = frame_of(cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(128)), interfaces::kCameraRgb8);
  std::string error;
  f->bytes -= 7;  // a truncated RGB frame
  EXPECT_FALSE(detector.detect(*f, intrinsics(), *out, error));
  EXPECT_NE(error.find("RGB8 frame 640x480 needs 921600 bytes, has 921593"), std::string::npos) << error;
  f->bytes += 7;
  f->format = 9;
  EXPECT_FALSE(detector.detect(*f, intrinsics(), *out, error));
  EXPECT_NE(error.find("format 9"), std::string::npos) << error;
  f->format = interfaces::kCameraJpeg;  // RGB bytes are no JPEG
  EXPECT_FALSE(detector.detect(*f, intrinsics(), *out, error));
  EXPECT_NE(error.find("does not decode"), std::string::npos) << error;
  f->format = interfaces::kCameraMono8;
  f->width = 0;
  EXPECT_FALSE(detector.detect(*f, intrinsics(), *out, error));
  EXPECT_NE(error.find("is not an image"), std::string::npos) << error;
  o.dictionary = "DICT_9X9";
  EXPECT_THROW(CameraDetector bad(o), std::invalid_argument);
  EXPECT_THROW((void)components::load_camera_calibration("/nonexistent/calib.yaml"), std::runtime_error);
}

TEST(CameraDetectorTest, PeopleDetectorFindsNobodyInAnEmptyRoom) {
  components::DetectorOptions o;
  o.people = true;
  CameraDetector detector(o);
  auto out = std::make_unique<ObjRecogData>();
  std::string error;
  cv::Mat image(kHeight, kWidth, CV_8UC1, cv::Scalar(128));
  cv::rectangle(image, cv::Rect(100, 300, 400, 120), cv::Scalar(60), cv::FILLED);  // a table-like block
  ASSERT_TRUE(detector.detect(*frame_of(image, interfaces::kCameraMono8), intrinsics(), *out, error)) << error;
  for (uint32_t i = 0; i < out->object_count; ++i) EXPECT_NE(out->type[i], interfaces::kObjTypePerson);
}

TEST(ObjRecogCameraTest, VelocityFromConsecutiveImagesByIdAndNearestPerson) {
  auto prev = std::make_unique<ObjRecogData>();
  auto cur = std::make_unique<ObjRecogData>();
  prev->object_count = 2;
  prev->type[0] = interfaces::kObjTypeFiducial;
  prev->id[0] = 4;
  prev->x[0] = 1.0F;
  prev->type[1] = interfaces::kObjTypePerson;
  prev->id[1] = 1000;
  prev->z[1] = 3.0F;
  cur->object_count = 3;
  cur->type[0] = interfaces::kObjTypePerson;  // the same person, 0.2 m closer
  cur->z[0] = 2.8F;
  cur->type[1] = interfaces::kObjTypeFiducial;
  cur->id[1] = 4;
  cur->x[1] = 1.1F;
  cur->type[2] = interfaces::kObjTypePerson;  // someone new, far from the first
  cur->x[2] = 2.0F;
  cur->z[2] = 3.0F;
  uint32_t next = 1001;
  components::ObjRecogCamera::follow(*prev, 1'000'000'000, *cur, 1'500'000'000, 0.7, next);
  EXPECT_EQ(cur->id[0], 1000U);
  EXPECT_NEAR(cur->vz[0], -0.4F, 1e-4F);
  EXPECT_NEAR(cur->vx[1], 0.2F, 1e-4F);
  EXPECT_EQ(cur->id[2], 1001U);
  EXPECT_EQ(cur->vx[2], 0.0F);
  EXPECT_EQ(next, 1002U);
}

// ---------------------------------------------------------------------------
// ObjRecogCamera in a real executor, fed by a test camera whose every third frame is
// broken (a byte count that does not match its size): the good frames give the
// marker with its pose and velocity, the bad ones are skipped and counted, and the
// component (and the rest of the host) stays ENABLED.

// Test code: renders in loop() (allocates); runs at priority 0.
class MarkerCamera final : public DataComponent<CameraData> {
 public:
  MarkerCamera() : DataComponent(DataTaskMode::kPeriodic) {}

 protected:
  void init() override { frame_ = std::make_unique<CameraData>(); }
  HookResult loop() override {
    ++n_;
    // The marker moves 0.02 m to the right per frame (period 50 ms: 0.4 m/s).
    const cv::Mat image = render({{9, {-0.2 + 0.02 * (n_ % 20), 0.0, 1.0}, rot_x(M_PI)}});
    *frame_ = *frame_of(image, interfaces::kCameraMono8);
    const CameraIntrinsics k = intrinsics();
    frame_->calibrated = 1;
    frame_->fx = k.fx;
    frame_->fy = k.fy;
    frame_->cx = k.cx;
    frame_->cy = k.cy;
    if (n_ % 3 == 0) frame_->bytes -= 100;  // broken
    publish(*frame_, rt::host_time_ns());
    return HookResult::kOk;
  }

 private:
  std::unique_ptr<CameraData> frame_;
  uint32_t n_ = 0;
};

TEST(ObjRecogCameraComponentTest, SkipsAndCountsBrokenFramesAndFollowsTheMarker) {
  Watchdog watchdog(std::chrono::seconds(60));
  HostUnderTest host(R"(lcm: false
components:
  - name: camera
    class: MarkerCamera
    data_task: {priority: 0, period_ms: 50, ring: 4}
  - name: objects
    class: ObjRecogCamera
    autostart: true
    data_task: {priority: 0, timeout_ms: 2000, ring: 8, input_slots: 2}
    params: {camera: camera, marker_length: 0.15, width: 640, height: 480}
)",
                     [](ComponentRegistry& r) {
                       r.add({"MarkerCamera", class_ids::kCamera, "test: rendered ArUco frames",
                              [] { return std::make_unique<MarkerCamera>(); }});
                     });
  const tims::Address objects = host.address_of("objects");
  ASSERT_TRUE(host.wait_status(objects, tims::msg::kEnabled)) << host.log();
  wire::SampleHeader sh{};
  auto d = std::make_unique<ObjRecogData>();
  // A sample with the marker moving right (not across the wrap from +0.18 back to -0.2).
  ASSERT_TRUE(eventually([&] {
    return host.get_data(objects, sh, *d) && d->bad_input >= 3 && d->inputs >= 6 && d->object_count == 1 &&
           d->vx[0] > 0.0F && d->vx[0] < 1.0F;
  })) << host.log();
  EXPECT_EQ(d->id[0], 9U);
  EXPECT_EQ(d->type[0], interfaces::kObjTypeFiducial);
  EXPECT_NEAR(d->z[0], 1.0F, 0.03F);
  // 0.02 m per camera cycle of 50 ms: 0.4 m/s, also across a skipped broken frame (the
  // velocity divides by the two good samples' times). Tolerant: under load the camera's
  // cycles come late (its steps are per cycle, not per time).
  EXPECT_GT(d->vx[0], 0.1F);
  EXPECT_LT(d->vx[0], 0.6F);
  EXPECT_EQ(host.status(objects), tims::msg::kEnabled) << "broken frames are skipped, not fatal";
  EXPECT_EQ(host.status(host.address_of("camera")), tims::msg::kEnabled);
}

// A "camera" that publishes another class's samples (WrongTypeProducer: ServoDriveData where CameraData
// is expected): each is dropped, counted as malformed input (GET_STATS) and as bad
// input of the object list, and logged with its source; the component stays ENABLED.
TEST(ObjRecogCameraComponentTest, SamplesOfTheWrongTypeAreCountedAsMalformedAndSkipped) {
  Watchdog watchdog(std::chrono::seconds(60));
  HostUnderTest host(R"(lcm: false
components:
  - name: camera
    class: WrongTypeCamera
    data_task: {priority: 0, period_ms: 20}
  - name: objects
    class: ObjRecogCamera
    autostart: true
    data_task: {priority: 0, timeout_ms: 30000, ring: 8, input_slots: 4}
    params: {camera: camera}
)",
                     [](ComponentRegistry& r) {
                       r.add({"WrongTypeCamera", class_ids::kCamera, "test: publishes ServoDriveData",
                              [] { return std::make_unique<WrongTypeProducer>(); }});
                     },
                     /*capture_gdos=*/true);
  const tims::Address objects = host.address_of("objects");
  ASSERT_TRUE(host.wait_status(objects, tims::msg::kEnabled)) << host.log();
  // Each wrong sample wakes the data task with nothing usable: skipped and counted; the
  // camera counts as silent only after timeout_ms without a frame.
  ASSERT_TRUE(eventually([&] { return host.stats(objects).malformed >= 5; })) << host.log();
  ASSERT_TRUE(eventually([&] {
    return host.gdos_log().find("input: dropped a DATA message of ") != std::string::npos;
  })) << host.gdos_log();
  EXPECT_EQ(host.status(objects), tims::msg::kEnabled) << host.log();
  EXPECT_EQ(host.stats(objects).errors, 0U) << host.log();
  EXPECT_EQ(host.status(host.address_of("camera")), tims::msg::kEnabled);
}

// ---------------------------------------------------------------------------
// Laser tracker.

// A scan (robot frame, beams every 0.5 deg over 360 deg) of circles (objects) and a
// straight wall, seen from the robot at `robot` (odometry frame).
struct Circle {
  double x, y, r;  // odometry frame
};
void render_scan(interfaces::Scan2dData& s, const components::Pose2d& robot, const std::vector<Circle>& circles,
                 double wall_y) {
  s = interfaces::Scan2dData{};
  const uint32_t beams = 720;
  s.max_range = 10.0F;
  for (uint32_t i = 0; i < beams; ++i) {
    const double a = -M_PI + i * (2 * M_PI / beams);
    const double wa = robot.phi + a;
    const double dx = std::cos(wa), dy = std::sin(wa);
    double best = 10.0;
    if (dy > 1e-6) best = std::min(best, (wall_y - robot.y) / dy);  // the wall y = wall_y
    for (const Circle& c : circles) {
      const double ox = robot.x - c.x, oy = robot.y - c.y;
      const double b = ox * dx + oy * dy, cc = ox * ox + oy * oy - c.r * c.r;
      const double disc = b * b - cc;
      if (disc >= 0 && -b - std::sqrt(disc) > 0) best = std::min(best, -b - std::sqrt(disc));
    }
    s.x[i] = static_cast<float>(best * std::cos(a));
    s.y[i] = static_cast<float>(best * std::sin(a));
    s.range[i] = static_cast<float>(best);
    s.bearing[i] = static_cast<float>(a);
    s.type[i] = best >= 10.0 ? interfaces::kScanPointMaxRange : interfaces::kScanPointNormal;
  }
  s.point_count = beams;
  s.odometry_x = robot.x;
  s.odometry_y = robot.y;
  s.odometry_phi = robot.phi;
  s.odometry_valid = 1;
}

// Stated tolerance: velocity within 0.05 m/s after 3 s of scans at 10 Hz.
TEST(LaserTrackerTest, AMovingClusterGetsItsVelocityAndIsMarkedDynamic) {
  components::LaserTracker tracker;
  tracker.set_options(components::TrackerOptions{});
  auto scan = std::make_unique<interfaces::Scan2dData>();
  const double vx = 0.6, vy = -0.3;
  for (int k = 0; k <= 30; ++k) {
    const double t = 0.1 * k;
    // The robot drives forward at 0.3 m/s: a static object must not seem to move.
    const components::Pose2d robot{0.3 * t, 0.0, 0.05 * t};
    render_scan(*scan, robot, {{1.5 + vx * t, 1.5 + vy * t, 0.15}, {3.0, -1.5, 0.2}}, 4.0);
    tracker.update(*scan, robot, static_cast<int64_t>(t * 1e9));
  }
  auto out = std::make_unique<ObjRecogData>();
  components::ObjRecogLaser::fill(tracker, *out);
  ASSERT_EQ(out->object_count, 2U) << "the two objects, not the wall";
  const components::Pose2d robot{0.9, 0.0, 0.15};
  int moving = -1, still = -1;
  for (uint32_t i = 0; i < 2; ++i) (std::hypot(out->vx[i], out->vy[i]) > 0.3 ? moving : still) = static_cast<int>(i);
  ASSERT_GE(moving, 0);
  ASSERT_GE(still, 0);
  // Velocities are over ground, expressed in the robot frame: turn them back.
  const double c = std::cos(robot.phi), s = std::sin(robot.phi);
  const auto m = static_cast<uint32_t>(moving);
  const double gvx = c * out->vx[m] - s * out->vy[m], gvy = s * out->vx[m] + c * out->vy[m];
  EXPECT_NEAR(gvx, vx, 0.05);
  EXPECT_NEAR(gvy, vy, 0.05);
  EXPECT_LT(std::hypot(out->vx[static_cast<uint32_t>(still)], out->vy[static_cast<uint32_t>(still)]), 0.05);
  EXPECT_EQ(out->type[m], interfaces::kObjTypeLaserCluster);
  EXPECT_EQ(out->frame, interfaces::kObjFrameRobot);
  // Position in the robot frame: the moving object's centre (the cluster's centroid
  // lies on the visible side: within its radius).
  const double ox = 1.5 + vx * 3.0 - robot.x, oy = 1.5 + vy * 3.0 - robot.y;
  EXPECT_NEAR(out->x[m], c * ox + s * oy, 0.15);
  EXPECT_NEAR(out->y[m], -s * ox + c * oy, 0.15);

  // Scan2D's marks: only the moving object's points become DYN_OBSTACLE.
  const uint32_t marked = tracker.mark_dynamic(*scan);
  EXPECT_GT(marked, 5U);
  uint32_t dyn = 0;
  for (uint32_t i = 0; i < scan->point_count; ++i) {
    if (scan->type[i] != interfaces::kScanPointDynObstacle) continue;
    ++dyn;
    const double px = robot.x + c * scan->x[i] - s * scan->y[i];
    const double py = robot.y + s * scan->x[i] + c * scan->y[i];
    EXPECT_LT(std::hypot(px - (1.5 + vx * 3.0), py - (1.5 + vy * 3.0)), 0.2) << "marked point off the moving object";
  }
  EXPECT_EQ(dyn, marked);
}

TEST(LaserTrackerTest, ObjectsAreConfirmedAfterHitsAndDroppedAfterMisses) {
  components::LaserTracker tracker;
  components::TrackerOptions o;
  o.confirm_hits = 3;
  o.max_missed = 2;
  tracker.set_options(o);
  auto scan = std::make_unique<interfaces::Scan2dData>();
  auto out = std::make_unique<ObjRecogData>();
  const components::Pose2d robot{};
  for (int k = 0; k < 2; ++k) {
    render_scan(*scan, robot, {{2.0, 0.0, 0.15}}, 5.0);
    tracker.update(*scan, robot, k * 100'000'000LL);
  }
  components::ObjRecogLaser::fill(tracker, *out);
  EXPECT_EQ(out->object_count, 0U) << "not confirmed after 2 hits";
  render_scan(*scan, robot, {{2.0, 0.0, 0.15}}, 5.0);
  tracker.update(*scan, robot, 200'000'000);
  components::ObjRecogLaser::fill(tracker, *out);
  ASSERT_EQ(out->object_count, 1U);
  const uint32_t id = out->id[0];
  for (int k = 3; k < 6; ++k) {  // gone for 3 scans
    render_scan(*scan, robot, {}, 5.0);
    tracker.update(*scan, robot, k * 100'000'000LL);
  }
  EXPECT_EQ(tracker.track_count(), 0U);
  render_scan(*scan, robot, {{2.0, 0.0, 0.15}}, 5.0);
  tracker.update(*scan, robot, 600'000'000);
  ASSERT_EQ(tracker.track_count(), 1U);
  EXPECT_NE(tracker.track(0).id, id) << "a new track after the old one was dropped";
}

}  // namespace
}  // namespace rack::test
