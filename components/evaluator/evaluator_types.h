// The declaration of this folder's classes, Evaluator and TrajectoryWriter
// (rack_add_class DATA in CMakeLists.txt): the sample type both publish
// (rack/interfaces/evaluation.h's EvaluatorData).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/evaluation.h"

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
