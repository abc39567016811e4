#include "rack/components/builtin.h"

#include "chassis_sim/chassis_sim.h"
#include "generator/generator.h"
#include "ladar_sim/ladar_sim.h"
#include "mcl/mcl.h"
#if RACK_HAVE_CAMERA
#include "camera/camera.h"
#endif
#include "chassis_can/chassis_can.h"
#include "generator/generator.h"
#include "gps_nmea/gps_nmea.h"
#include "joystick/joystick.h"
#include "ladar_hokuyo/ladar_hokuyo.h"
#include "ladar_sick/ladar_sick.h"
#include "servo_drive_can/servo_drive_can.h"
#include "monitor/monitor.h"
#include "odometry/odometry.h"
#include "path/path.h"
#include "pilot/pilot.h"
#include "position/position.h"
#include "evaluator/evaluator.h"
#include "evaluator/trajectory_writer.h"
#include "modeswitch_demo/modeswitch_demo.h"
#include "probe/probe.h"
#include "replay/replay_components.h"
#include "scan2d/scan2d.h"
#include "obj_recog/obj_recog_laser.h"
#if RACK_HAVE_OBJRECOG_CAMERA
#include "obj_recog/obj_recog_camera.h"
#endif
#include "scan3d/scan3d.h"
#include "servo_drive_sim/servo_drive_sim.h"
#include "rack/interfaces/data_types.h"
#include "rack/tims/address.h"

namespace rack::components {

namespace {
// Adds a class with the sample type and class commands of its TiMS class.
class Adder {
 public:
  explicit Adder(ComponentRegistry& registry) : registry_(registry) {}
  void add(ComponentClass cls) {
    cls.data = interfaces::data_type_for_class(cls.class_id);
    cls.commands = interfaces::commands_for_class(cls.class_id);
    registry_.add(std::move(cls));
  }

 private:
  ComponentRegistry& registry_;
};
}  // namespace

void register_builtin(ComponentRegistry& target) {
  namespace cls = tims::classes;
  Adder registry(target);
  registry.add({"Generator", cls::kGenerator, "demo: periodic sine producer",
                [] { return std::make_unique<Generator>(); }});
  registry.add({"Monitor", cls::kMonitor, "demo: subscribes to a Generator and reports what it received",
                [] { return std::make_unique<Monitor>(); }});
  registry.add({"Probe", cls::kProbe, "test: hooks fail or throw on demand",
                [] { return std::make_unique<Probe>(); }});
  registry.add({"MCL", cls::kMcl, "Monte Carlo localisation on MRPT: Scan2D + map -> pose; Position UPDATE",
                [] { return std::make_unique<Mcl>(); }});
  registry.add({"ChassisReplay", cls::kChassis, "replay: a CARMEN log or MRPT rawlog's odometry as Chassis increments",
                [] { return std::make_unique<ChassisReplay>(); }});
  registry.add({"LadarReplay", cls::kLadar, "replay: a CARMEN log or MRPT rawlog's laser scans as Ladar data",
                [] { return std::make_unique<LadarReplay>(); }});
  // The simulated robot and navigation (README: "Simulated robot and navigation").
  registry.add({"ChassisSim", cls::kChassis, "simulated drive: velocity commands, odometry with noise, true pose",
                [] { return std::make_unique<ChassisSim>(); }});
  registry.add({"LadarSim", cls::kLadar, "simulated laser scanner: ray-casts a map_server map from the true pose",
                [] { return std::make_unique<LadarSim>(); }});
  registry.add({"Odometry", cls::kOdometry, "integrates a Chassis' increments; getData(t) gives the odometry at t",
                [] { return std::make_unique<Odometry>(); }});
  registry.add({"Position", cls::kPosition, "pose = reference (UPDATE at a time) + odometry since that time",
                [] { return std::make_unique<Position>(); }});
  registry.add({"Scan2D", cls::kScan2d, "ladar scans as robot-frame points (mounting, range window, median)",
                [] { return std::make_unique<Scan2d>(); }});
  registry.add({"Path", cls::kPath, "spline path through waypoints (parameter or MAKE)",
                [] { return std::make_unique<Path>(); }});
  registry.add({"Pilot", cls::kPilot, "pure-pursuit pilot: follows a Path or goes to a destination, obstacle speed limit",
                [] { return std::make_unique<Pilot>(); }});
  registry.add({"Evaluator", cls::kEvaluator,
                "simulation: localisation error of Position and MCL against ChassisSim's true pose",
                [] { return std::make_unique<Evaluator>(); }});
  registry.add({"TrajectoryWriter", cls::kEvaluator,
                "evaluation: writes MCL's (or Position's) estimates as 't x y theta' lines; ATE, lost poses and "
                "rotation error against a reference file at the end",
                [] { return std::make_unique<TrajectoryWriter>(); }});
  registry.add({"ModeSwitchDemo", cls::kModeSwitchDemo,
                "demo: class commands that trigger each mode-switch reason and a crash (configs/modeswitch_demo.yaml)",
                [] { return std::make_unique<ModeSwitchDemo>(); }});
  // Hardware drivers (issue 8); simulators for each: rack-devsim.
  registry.add({"GpsNmea", cls::kGps, "GPS: NMEA 0183 receiver on a serial port (GGA/RMC/GSA/VTG, UTM, local x/y)",
                [] { return std::make_unique<GpsNmea>(); }});
  registry.add({"ChassisCan", cls::kChassis,
                "Chassis: differential drive with two CiA 402 drives over SocketCAN (profile velocity)",
                [] { return std::make_unique<ChassisCan>(); }});
  registry.add({"LadarHokuyo", cls::kLadar, "Ladar: Hokuyo URG/UTM scanner, SCIP 2.0 over serial or USB-ACM",
                [] { return std::make_unique<LadarHokuyo>(); }});
  registry.add({"LadarSick", cls::kLadar, "Ladar: SICK LMS1xx/LMS5xx/TiM5xx over TCP (CoLa-A, continuous output)",
                [] { return std::make_unique<LadarSick>(); }});
  registry.add({"ServoDriveCan", cls::kServoDrive,
                "ServoDrive: one axis on a CiA 402 drive over SocketCAN (profile position; HOME, MOVE_POS, MOVE_VEL)",
                [] { return std::make_unique<ServoDriveCan>(); }});
  // Perception (issue 9): README "Perception: 3-D scans and object recognition".
  registry.add({"ServoDriveSim", cls::kServoDrive,
                "simulated servo axis (HOME, MOVE_POS, MOVE_VEL; trapezoidal profile), e.g. to turn LadarSim for Scan3D",
                [] { return std::make_unique<ServoDriveSim>(); }});
  registry.add({"Scan3D", cls::kScan3d,
                "3-D scans from a Ladar on a ServoDrive (roll/pitch/yaw) or PCD files; PCL voxel grid, outliers, ground plane",
                [] { return std::make_unique<Scan3d>(); }});
  registry.add({"ObjRecogLaser", cls::kObjRecog,
                "objects from Scan2D: clusters tracked with position and velocity (nearest neighbour + Kalman)",
                [] { return std::make_unique<ObjRecogLaser>(); }});
#if RACK_HAVE_OBJRECOG_CAMERA
  registry.add({"ObjRecogCamera", cls::kObjRecog,
                "objects in Camera images: ArUco fiducials with 3-D pose, people (HOG); OpenCV",
                [] { return std::make_unique<ObjRecogCamera>(); }});
#endif
#if RACK_HAVE_CAMERA
  registry.add({"Camera", cls::kCamera, "Camera: OpenCV VideoCapture (V4L2 device, video file, image sequence)",
                [] { return std::make_unique<Camera>(); }});
#endif
  registry.add({"Joystick", cls::kJoystick, "Joystick: Linux joystick API; optionally the active pilot of a chassis",
                [] { return std::make_unique<Joystick>(); }});
}

}  // namespace rack::components
