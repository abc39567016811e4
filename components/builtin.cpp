#include "rack/components/builtin.h"

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
#include "probe/probe.h"
#include "rack/tims/address.h"

namespace rack::components {

void register_builtin(ComponentRegistry& registry) {
  namespace cls = tims::classes;
  registry.add({"Generator", cls::kGenerator, "demo: periodic sine producer",
                [] { return std::make_unique<Generator>(); }});
  registry.add({"Monitor", cls::kMonitor, "demo: subscribes to a Generator and reports what it received",
                [] { return std::make_unique<Monitor>(); }});
  registry.add({"Probe", cls::kProbe, "test: hooks fail or throw on demand",
                [] { return std::make_unique<Probe>(); }});
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
#if RACK_HAVE_CAMERA
  registry.add({"Camera", cls::kCamera, "Camera: OpenCV VideoCapture (V4L2 device, video file, image sequence)",
                [] { return std::make_unique<Camera>(); }});
#endif
  registry.add({"Joystick", cls::kJoystick, "Joystick: Linux joystick API; optionally the active pilot of a chassis",
                [] { return std::make_unique<Joystick>(); }});
}

}  // namespace rack::components
