// The declaration of this folder's classes, Evaluator and TrajectoryWriter
// (rack_add_class DATA in CMakeLists.txt): the sample type both publish
// (EvaluatorData). Evaluator: how far the robot's estimates are from the simulated
// truth (ChassisSim's true pose at the same time); simulation only, a real robot has no
// truth to compare with. TrajectoryWriter: the estimate against a reference trajectory.
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include <array>
#include <cstdint>

#include "rack/core/class_types.h"
#include "rack/tims/payload.h"

// The payload types (namespace rack::interfaces, as every sample type's, so that code
// naming them did not change when they moved here from components/interfaces).
namespace rack::interfaces {

struct EvaluatorData {
  double distance = 0.0;  // m the robot truly travelled since ON
  // Position (the pose the pilot steers on) against the truth at its sample time.
  uint64_t position_samples = 0;
  double position_error = 0.0;        // m, the last sample's
  double position_rms = 0.0;          // m, over every sample since ON
  double position_p95 = 0.0;          // m, 1 mm resolution below 10 m; beyond: the max (an upper bound)
  double position_max = 0.0;          // m
  double position_heading_rms = 0.0;  // rad
  // MCL's estimate against the truth at its scan's time.
  uint64_t mcl_samples = 0;
  double mcl_error = 0.0;
  double mcl_rms = 0.0;
  double mcl_p95 = 0.0;
  double mcl_max = 0.0;
  double mcl_heading_rms = 0.0;
  uint64_t unmatched = 0;  // estimates with no truth sample within 20 ms of their time
                           // (TrajectoryWriter: reference poses without an estimate)
  uint64_t lost = 0;       // TrajectoryWriter: reference poses estimated further off than
                           // lost_threshold (the mcl_* fields: ATE against the reference)
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(EvaluatorData, distance),
                      RACK_FIELD(EvaluatorData, position_samples),
                      RACK_FIELD(EvaluatorData, position_error),
                      RACK_FIELD(EvaluatorData, position_rms),
                      RACK_FIELD(EvaluatorData, position_p95),
                      RACK_FIELD(EvaluatorData, position_max),
                      RACK_FIELD(EvaluatorData, position_heading_rms),
                      RACK_FIELD(EvaluatorData, mcl_samples),
                      RACK_FIELD(EvaluatorData, mcl_error),
                      RACK_FIELD(EvaluatorData, mcl_rms),
                      RACK_FIELD(EvaluatorData, mcl_p95),
                      RACK_FIELD(EvaluatorData, mcl_max),
                      RACK_FIELD(EvaluatorData, mcl_heading_rms),
                      RACK_FIELD(EvaluatorData, unmatched),
                      RACK_FIELD(EvaluatorData, lost)};
  }
};

}  // namespace rack::interfaces

namespace rack::components {

inline constexpr FieldUnit kEvaluatorUnits[] = {{"distance", "m"},         {"position_error", "m"},
                                                {"position_rms", "m"},     {"position_p95", "m"},
                                                {"position_max", "m"},     {"position_heading_rms", "rad"},
                                                {"mcl_error", "m"},        {"mcl_rms", "m"},
                                                {"mcl_p95", "m"},          {"mcl_max", "m"},
                                                {"mcl_heading_rms", "rad"}};
inline constexpr DataTypeInfo kEvaluatorType = data_type_info<interfaces::EvaluatorData>("EvaluatorData", {},
                                                                                         kEvaluatorUnits);

}  // namespace rack::components
