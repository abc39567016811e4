// Path (class Path): a smooth path through waypoints, published for pilots.
//
// The path is a centripetal Catmull-Rom spline (it passes through every waypoint and,
// unlike the uniform variant, never makes loops or cusps between close waypoints),
// sampled every `resolution` metres. Waypoints come from the `waypoints` parameter
// ("x,y; x,y; ...", metres in the map frame) or from a MAKE command. A periodic data
// task publishes a path when one was made: at ON, after MAKE, and when the
// `waypoints`, `closed` or `resolution` parameter changed (so `rackctl set-param path waypoints ...`
// re-plans). A malformed waypoint text is counted in `rejected` with its reason in
// `last_error`, and the previous path stays.
//
// Threads: MAKE (command task) builds into a pending path under a PI mutex; the data
// task publishes it. Real-time contract: everything after init() is RT-safe (fixed
// arrays; parsing with strtod, no allocation).
#pragma once

#include <atomic>

#include "rack/core/data_component.h"
#include "rack/core/handoff.h"
#include "rack/interfaces/navigation.h"

namespace rack::components {

class Path final : public DataComponent<interfaces::PathData> {
 public:
  Path();

  // Parses "x,y; x,y; ..." into `out` (count set, closed untouched). nullptr on
  // success, else a static reason; `item` gets the 1-based waypoint at fault. RT-safe.
  static const char* parse_waypoints(const char* text, interfaces::PathMake& out, int& item) noexcept;
  // Makes the sampled spline (waypoints, points, length, closed). nullptr on success,
  // else a static reason (out is then unspecified): 2..32 waypoints, finite and within
  // 1000 km of the map origin (the sample's floats), no two consecutive ones equal. RT-safe.
  static const char* make_path(const interfaces::PathMake& waypoints, double resolution,
                               interfaces::PathData& out) noexcept;

 protected:
  void init() override;
  [[nodiscard]] bool check_parameters(const ParameterValues& values, ParameterProblem& problem) const noexcept override;
  HookResult on() override;
  HookResult loop() override;  // RT
  CommandResult command(const tims::MessageHeader& request, std::span<const std::byte> body) override;

 private:
  // Builds from the parameters into `out`; on failure writes the reason to `error`.
  bool make_from_parameters(interfaces::PathData& out, char (&error)[96]) noexcept;

  Parameter& waypoints_;
  Parameter& closed_;
  Parameter& resolution_;

  Handoff<interfaces::PathData> made_;    // made by MAKE, published by the data task
  interfaces::PathData scratch_{};        // command task: MAKE builds here first
  mutable interfaces::PathData check_{};  // check_parameters (command task, or set-up before it runs)

  // Data task.
  interfaces::PathData current_{};
  char last_text_[wire::kParamStringLen] = {};
  bool last_closed_ = false;
  double last_resolution_ = 0.0;
  uint32_t makes_ = 0;
  uint32_t rejected_ = 0;
  char last_error_[96] = {};
  // MAKE rejections (command task), merged into `rejected` by the data task (relaxed: a counter).
  std::atomic<uint32_t> make_rejected_{0};
};

}  // namespace rack::components
