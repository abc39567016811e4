// Evaluator's error statistics: p95 from the 1-mm histogram, and beyond its 10 m
// (the open last bucket) the largest error instead of a silent 10 m.
#include <gtest/gtest.h>

#include "evaluator/evaluator.h"

namespace rack::components {
namespace {

using Stats = Evaluator::ErrorStats;

TEST(EvaluatorStatsTest, P95IsTheUpperEdgeOfItsBucket) {
  Stats s;
  for (int i = 0; i < 100; ++i) s.add(i < 95 ? 0.0105 : 2.0, 0.0);
  EXPECT_DOUBLE_EQ(s.p95(), 0.011);  // 10.5 mm lies in [10, 11) mm
}

TEST(EvaluatorStatsTest, P95BeyondTenMetresIsTheMaxNotTenMetres) {
  Stats s;
  for (int i = 0; i < 100; ++i) s.add(i < 90 ? 0.5 : 15.0 + i * 0.01, 0.0);
  EXPECT_GT(s.p95(), 10.0);
  EXPECT_DOUBLE_EQ(s.p95(), s.max);
  EXPECT_DOUBLE_EQ(s.max, 15.99);
}

TEST(EvaluatorStatsTest, NoSamplesNoP95) { EXPECT_EQ(Stats{}.p95(), 0.0); }

}  // namespace
}  // namespace rack::components
