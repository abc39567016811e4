// Pilot (class Pilot): drives the chassis along the Path component's path or straight
// to a destination, on the Position estimate, with pure-pursuit steering (Coulter,
// "Implementation of the Pure Pursuit Path Tracking Algorithm", CMU-RI-TR-92-01):
// aim at the path point `lookahead` metres ahead and drive the arc through it.
//
// Speed: at most the chassis' vx_max and the `vx_max` parameter, slower in tight
// arcs (omega_max), braking towards the end of an open path or a destination, and
// limited by the nearest obstacle in the Scan2D data: the free distance d ahead of
// the outline (in the corridor the outline sweeps, widened by the safety margin)
// allows v = sqrt(2 * brake * (d - margin)); a point inside outline + margin stops
// the robot (status BLOCKED) until it is gone. The outline, margin and limits come
// from the chassis (GET_PARAMS) at ON.
//
// Arbitration: ON makes this pilot the chassis' active pilot (SET_ACTIVE_PILOT) and
// it then sends a MOVE every cycle (which also feeds the chassis watchdog). When the
// chassis refuses a MOVE (another pilot took over) the pilot stands (PREEMPTED)
// until it is told where to go again. OFF stops the robot.
//
// What to do: the `mode` parameter at ON (path, hold), FOLLOW_PATH, HOLD and
// SET_DESTINATION commands, or the `destination` parameter ("x,y"; set it with
// rackctl set-param to send the robot somewhere; "" goes back to the path, also
// after a SET_DESTINATION: every SET_PARAM of it is an order, changed or not).
//
// Planning: with a `map` (the localisation map, ROS map_server YAML), a destination
// is reached along a planned way (GridPlanner, path/planner.h: A* on the map inflated
// by the circle round the chassis' outline plus `plan_margin`, shortened to waypoints
// and smoothed by Path's spline) instead of a straight line. SET_DESTINATION plans at
// once from the Position estimate and answers ERROR with the reason when there is no
// way (in a wall, outside the map, cut off); a `destination` parameter is planned on
// the next cycle (status PLANNING, then DRIVING or UNREACHABLE). Standing BLOCKED on a
// planned way for `replan_blocked_ms`, the pilot plans again round the points its
// scanner sees (GDOS info says so); following the path, it plans a way back to the
// path's look-ahead point (e.g. from a room, or after a bad INIT put it against a
// wall) and follows the path again at its end. Without a map, destinations are driven
// straight.
//
// GDOS (info): commands received, destinations planned or refused, BLOCKED (once per
// stop), replanning.
//
// Threads: commands (command task) hand orders to the data task through a Handoff.
// Plans run in the command task (a few ms, no allocation): the data task asks for one
// with a message to its own command mailbox (kPlanSelf), never plans itself.
// Real-time contract: on(), off(), loop() and command() are RT-safe; init() allocates
// (and loads the map).
#pragma once

#include <vector>

#include "common/pose2d.h"
#include "path/planner.h"
#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "pilot_types.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Pilot final : public DataComponent<interfaces::PilotData> {
 public:
  Pilot();

  struct Outline {
    double front = 0.3, back = 0.3, left = 0.25, right = 0.25, margin = 0.1;
  };
  struct Clearance {
    double free_ahead = 0.0;    // m from the front of the outline to the nearest point in the swept corridor
    bool inside = false;        // a point lies inside outline + margin
    bool turn_blocked = false;  // a point lies inside the circle the outline sweeps when turning in place
  };
  // Obstacle clearance of a robot-frame scan (pure, RT-safe). Max-range points are ignored.
  static Clearance clearance(const interfaces::Scan2dData& scan, const Outline& o) noexcept;

 protected:
  void init() override;
  [[nodiscard]] bool check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept override;
  HookResult on() override;
  void off() override;
  HookResult loop() override;  // RT, periodic
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  enum class Request : uint8_t { kNone, kFollowPath, kHold, kDestination, kPlanned, kPlanFailed };
  // The data task's request for a plan (to its own command mailbox; native layout).
  static constexpr int8_t kPlanSelf = 99;
  static constexpr uint32_t kPlanObstacles = 96;
  struct PlanRequest {
    double gx = 0.0, gy = 0.0;           // the destination
    double x = 0.0, y = 0.0, phi = 0.0;  // the robot
    uint32_t obstacles = 0;              // scan points to plan round (map frame)
    uint32_t replan = 0;                 // 1: blocked on the way
    float ox[kPlanObstacles] = {}, oy[kPlanObstacles] = {};
  };
  // Command task: plans from (x, y) to (gx, gy) and hands the way to the data task.
  // nullptr on success, else the reason.
  const char* plan_way(const PlanRequest& r) noexcept;
  // Command task: hands an order to the data task (the newest wins); kPlanned with the way.
  void give_order(Request kind, double x = 0.0, double y = 0.0, const interfaces::PathData* plan = nullptr) noexcept;
  void ask_for_plan(const Pose2d& pose, bool replan) noexcept;  // data task
  // Takes the inputs' samples; true when a source (position, scan2d) left ENABLED.
  [[nodiscard]] bool handle_input(int64_t now) noexcept;
  [[nodiscard]] bool parse_destination(const char* text, double& x, double& y) const noexcept;
  // Steering towards `goal` (map frame); fills vx/omega in data_. `final_distance`
  // is how far the robot still has to go (braking), < 0 for an endless path.
  void steer(const Pose2d& pose, double gx, double gy, double final_distance) noexcept;
  // Picks the pure-pursuit goal on the path; false when the path is finished.
  bool path_goal(const interfaces::PathData& p, bool& fresh, const Pose2d& pose, double& gx, double& gy,
                 double& remaining) noexcept;
  void send_move(double vx, double omega) noexcept;

  Parameter& chassis_;
  // Declared inputs: stale after silence_ms (the robot stands, status NO_INPUT); a
  // position or scan2d ERROR fails the pilot (re-subscribed on retry), a path's not.
  InputOf<interfaces::PositionData>& position_;
  InputOf<interfaces::Scan2dData>& scan2d_;
  InputOf<interfaces::PathData>& path_;
  Parameter& mode_;
  Parameter& destination_;
  Parameter& vx_max_;
  Parameter& omega_max_;
  Parameter& lookahead_;
  Parameter& goal_tolerance_;
  Parameter& turn_in_place_deg_;
  Parameter& brake_fraction_;
  Parameter& map_;
  Parameter& plan_margin_;
  Parameter& replan_blocked_ms_;

  // Command task (the planner is set up by init()).
  GridPlanner planner_;
  double plan_radius_ = 0.0;  // m, the circle round the outline (on())
  interfaces::PathData plan_scratch_{};

  // Command task -> data task.
  struct Order {
    Request kind = Request::kNone;
    double x = 0.0, y = 0.0;    // the destination
    interfaces::PathData plan;  // with kPlanned: the way there
  };
  Handoff<Order> orders_;
  Order order_;  // data task: the order taken

  // Set in on() (before the data task runs loop()), read by the data task.
  interfaces::ChassisParams limits_{};
  Outline outline_;

  // Data task.
  interfaces::PilotData data_{};
  // Destination mode drives along the line from where the robot was when it got the
  // destination (pure pursuit on that line, so it arrives straight, e.g. through a door).
  double line_x_ = 0.0, line_y_ = 0.0;
  bool line_pending_ = false;  // the line starts at the next pose
  double goal_bearing_ = 0.0;  // rad, the goal seen from the robot (set by steer())
  bool have_path_ = false;
  bool path_fresh_ = false;           // a new path arrived: find the nearest point again
  interfaces::PathData plan_data_{};  // the planned way to the destination
  bool have_plan_ = false, plan_fresh_ = false;
  bool plan_asked_ = false;  // a kPlanSelf is on its way
  bool join_path_ = false;   // the planned way leads back to the path
  int64_t plan_asked_ns_ = 0;
  int64_t blocked_since_ns_ = 0;     // 0: not blocked
  uint32_t destination_writes_ = 0;  // destination_.write_count() seen
  int64_t position_mono_ns_ = 0;
  int64_t scan_mono_ns_ = 0;
  bool have_scan_ = false;
  char last_destination_[wire::kParamStringLen] = {};
  std::vector<std::byte> rpc_buffer_;  // command task (on(): the Path's newest sample)
};

}  // namespace rack::components
