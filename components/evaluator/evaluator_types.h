// The declaration of this folder's classes, Evaluator and TrajectoryWriter
// (rack_add_class DATA in CMakeLists.txt): the sample type both publish
// (rack/interfaces/evaluation.h's EvaluatorData).
//
// Real-time contract: constant data; reading it is RT-safe.
#pragma once

#include "rack/core/class_types.h"
#include "rack/interfaces/evaluation.h"

namespace rack::components {

inline constexpr DataTypeInfo kEvaluatorType = data_type_info<interfaces::EvaluatorData>("EvaluatorData");

}  // namespace rack::components
