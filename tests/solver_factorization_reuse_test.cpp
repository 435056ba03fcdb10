// When a Levenberg-Marquardt step is first tried on an earlier factorization, and when such a
// step is kept: each condition at its boundary.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../solver/src/factorization_reuse.hpp"
#include "../solver/src/step_quality.hpp"

namespace carat {
namespace {

using internal::StepQuality;

/// An accepted fresh step: gain ratio `ratio`, predicted decrease `predicted` at rounding 1e-9.
StepQuality accepted(double ratio, double predicted) {
  StepQuality step;
  step.gain_ratio = ratio;
  step.measured_ratio = ratio;
  step.model_decrease = predicted;
  step.rounding = 1e-9;
  step.cost_is_finite = true;
  return step;
}

/// A step on an earlier factorization: measured ratio `ratio`, cost decrease `decrease`.
StepQuality reused(double ratio, double decrease) {
  StepQuality step;
  step.measured_ratio = ratio;
  step.gain_ratio = ratio;
  step.cost_decrease = decrease;
  step.cost_is_finite = std::isfinite(decrease);
  return step;
}

TEST(FactorizationReuseTest, TriedOnlyAfterAGainRatioAboveTheSetOne) {
  SolverOptions options;
  options.factor_reuse_ratio = 1.1;
  EXPECT_FALSE(internal::should_try_reuse(accepted(1.1, 1.0), options));
  EXPECT_TRUE(internal::should_try_reuse(accepted(std::nextafter(1.1, 2.0), 1.0), options));
  EXPECT_FALSE(internal::should_try_reuse(accepted(0.9, 1.0), options));
  options.reuse_factorization = false;
  EXPECT_FALSE(internal::should_try_reuse(accepted(2.0, 1.0), options));
}

TEST(FactorizationReuseTest, TriedOnlyWhenThePredictedDecreaseIsWellAboveTheRounding) {
  const SolverOptions options;
  // Rounding 1e-9: the predicted decrease must exceed 1e-6.
  EXPECT_FALSE(internal::should_try_reuse(accepted(2.0, 1e3 * 1e-9), options));
  EXPECT_TRUE(internal::should_try_reuse(accepted(2.0, 2e-6), options));
}

TEST(FactorizationReuseTest, KeptOnlyAboveHalfTheModelsDecrease) {
  // fresh decrease 1, cost 100, function tolerance 1e-6 (threshold 1e-4).
  EXPECT_FALSE(internal::keeps_reused_step(reused(0.5, 1.0), 1.0, 100.0, 1e-6));
  EXPECT_TRUE(internal::keeps_reused_step(reused(std::nextafter(0.5, 1.0), 1.0), 1.0, 100.0, 1e-6));
}

TEST(FactorizationReuseTest, KeptOnlyWhileItLowersTheCostHalfAsMuchAsAFreshStep) {
  EXPECT_TRUE(internal::keeps_reused_step(reused(1.0, 0.5), 1.0, 100.0, 1e-6));
  EXPECT_FALSE(
      internal::keeps_reused_step(reused(1.0, std::nextafter(0.5, 0.0)), 1.0, 100.0, 1e-6));
}

TEST(FactorizationReuseTest, KeptOnlyAboveTheFunctionTolerance) {
  // cost 8, tolerance 1/4: the decrease must exceed 2 (strictly); fresh decrease 0.
  EXPECT_FALSE(internal::keeps_reused_step(reused(1.0, 2.0), 0.0, 8.0, 0.25));
  EXPECT_TRUE(internal::keeps_reused_step(reused(1.0, 2.5), 0.0, 8.0, 0.25));
}

TEST(FactorizationReuseTest, NeverKeptWithANonFiniteCost) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(internal::keeps_reused_step(reused(nan, nan), 0.0, 8.0, 0.0));
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(internal::keeps_reused_step(reused(-inf, -inf), 0.0, 8.0, 0.0));
}

TEST(FactorizationReuseTest, ASlowTailIsMarkedWhetherOrNotReuseIsOn) {
  SolverOptions options;
  options.reuse_factorization = false;
  EXPECT_TRUE(internal::is_slow_tail_step(accepted(std::nextafter(1.1, 2.0), 1.0), options));
  EXPECT_FALSE(internal::is_slow_tail_step(accepted(1.1, 1.0), options));
  EXPECT_FALSE(internal::is_slow_tail_step(accepted(2.0, 1e3 * 1e-9), options));
  EXPECT_FALSE(internal::should_try_reuse(accepted(2.0, 1.0), options));
}

TEST(FactorizationReuseTest, AnAcceleratedTailKeepsStepsDownToATenthOfAFreshOne) {
  // fresh decrease 1, cost 100, function tolerance 1e-6: the decrease must reach 0.1, whatever
  // the ratio (Anderson's step has no model of its own).
  EXPECT_TRUE(internal::keeps_accelerated_tail_step(reused(0.2, 0.1), 1.0, 100.0, 1e-6));
  EXPECT_FALSE(internal::keeps_accelerated_tail_step(reused(1.0, std::nextafter(0.1, 0.0)), 1.0,
                                                     100.0, 1e-6));
  // Above the function tolerance strictly (cost 8, tolerance 1/4, fresh decrease 0) ...
  EXPECT_TRUE(internal::keeps_accelerated_tail_step(reused(1.0, 2.5), 0.0, 8.0, 0.25));
  // ... or, at or below it, a step that agrees with the model ends the solve as a probe would.
  EXPECT_TRUE(internal::keeps_accelerated_tail_step(reused(0.9, 2.0), 0.0, 8.0, 0.25));
  EXPECT_FALSE(internal::keeps_accelerated_tail_step(reused(0.4, 2.0), 0.0, 8.0, 0.25));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(internal::keeps_accelerated_tail_step(reused(nan, nan), 0.0, 8.0, 0.0));
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(internal::keeps_accelerated_tail_step(reused(-inf, inf), 0.0, 8.0, 0.0));
}

}  // namespace
}  // namespace carat
