// The tests that end a solve, each on its own: which one fires at its boundary, with which
// termination type and message.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../solver/src/stop_criteria.hpp"

namespace carat {
namespace {

using internal::RadiusShrinkCause;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(StopCriteriaTest, GradientToleranceIsInclusive) {
  const auto stop = internal::check_gradient_tolerance(1e-10, 1e-10);
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->type, TerminationType::kConvergence);
  EXPECT_EQ(stop->message, "gradient tolerance reached: max |gradient| = 1e-10");
  EXPECT_FALSE(internal::check_gradient_tolerance(std::nextafter(1e-10, 1.0), 1e-10));
  EXPECT_FALSE(internal::check_gradient_tolerance(kNaN, 1e-10));
}

TEST(StopCriteriaTest, IterationLimitFiresOnceEveryIterationIsUsed) {
  EXPECT_FALSE(internal::check_iteration_limit(49, 50));
  const auto stop = internal::check_iteration_limit(50, 50);
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->type, TerminationType::kNoConvergence);
  EXPECT_EQ(stop->message, "maximum number of iterations reached (50)");
  // max_iterations = 0: no iteration at all.
  EXPECT_TRUE(internal::check_iteration_limit(0, 0));
}

TEST(StopCriteriaTest, ParameterToleranceScalesWithTheParameters) {
  const double tolerance = 0.25;
  // |x| = 3.75: the step may be up to 0.25 * (3.75 + 0.25) = 1.
  const auto stop = internal::check_parameter_tolerance(1.0, 3.75, tolerance);
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->type, TerminationType::kConvergence);
  EXPECT_EQ(stop->message, "parameter tolerance reached: |step| = 1");
  EXPECT_FALSE(internal::check_parameter_tolerance(std::nextafter(1.0, 2.0), 3.75, tolerance));
  // At |x| = 0 the tolerance is absolute: tolerance^2.
  EXPECT_TRUE(internal::check_parameter_tolerance(0.0625, 0.0, tolerance));
  EXPECT_FALSE(internal::check_parameter_tolerance(0.07, 0.0, tolerance));
  EXPECT_FALSE(internal::check_parameter_tolerance(kNaN, 1.0, tolerance));
}

TEST(StopCriteriaTest, FunctionToleranceTestsTheAbsoluteRelativeChange) {
  // cost 8, tolerance 1/4: a change of at most 2 either way converges.
  const auto fell = internal::check_function_tolerance(2.0, 8.0, 0.25);
  ASSERT_TRUE(fell);
  EXPECT_EQ(fell->type, TerminationType::kConvergence);
  EXPECT_EQ(fell->message, "function tolerance reached: |cost change| / cost = 0.25");
  const auto rose = internal::check_function_tolerance(-2.0, 8.0, 0.25);
  ASSERT_TRUE(rose);
  EXPECT_EQ(rose->message, fell->message);
  EXPECT_FALSE(internal::check_function_tolerance(2.5, 8.0, 0.25));
  EXPECT_FALSE(internal::check_function_tolerance(-2.5, 8.0, 0.25));
  // A zero cost that stays zero: converged, relative change reported as 0.
  const auto zero = internal::check_function_tolerance(0.0, 0.0, 1e-6);
  ASSERT_TRUE(zero);
  EXPECT_EQ(zero->message, "function tolerance reached: |cost change| / cost = 0");
}

TEST(StopCriteriaTest, TrustRegionCollapseIsStrictAndNamesItsCause) {
  EXPECT_FALSE(internal::check_trust_region_radius(1e-32, 1e-32, RadiusShrinkCause::kStepRejected));
  const auto rejected = internal::check_trust_region_radius(std::nextafter(1e-32, 0.0), 1e-32,
                                                            RadiusShrinkCause::kStepRejected);
  ASSERT_TRUE(rejected);
  EXPECT_EQ(rejected->type, TerminationType::kNoConvergence);
  EXPECT_EQ(rejected->message, "trust region radius below min_trust_region_radius");
  const auto indefinite = internal::check_trust_region_radius(
      1e-40, 1e-32, RadiusShrinkCause::kSystemNotPositiveDefinite);
  ASSERT_TRUE(indefinite);
  EXPECT_EQ(indefinite->type, TerminationType::kNoConvergence);
  EXPECT_EQ(indefinite->message,
            "trust region radius below min_trust_region_radius (system not positive definite)");
}

TEST(StopCriteriaTest, GaussNewtonStopsWhenTheStepDoesNotLowerTheCost) {
  EXPECT_FALSE(internal::check_gauss_newton_decrease(5.0, 4.0));
  EXPECT_FALSE(internal::check_gauss_newton_decrease(5.0, 5.0));  // an equal cost is taken
  const auto rose = internal::check_gauss_newton_decrease(5.0, std::nextafter(5.0, 6.0));
  ASSERT_TRUE(rose);
  EXPECT_EQ(rose->type, TerminationType::kNoConvergence);
  EXPECT_EQ(rose->message, "Gauss-Newton step did not decrease the cost");
  for (const double trial : {kNaN, std::numeric_limits<double>::infinity()}) {
    const auto bad = internal::check_gauss_newton_decrease(5.0, trial);
    ASSERT_TRUE(bad) << trial;
    EXPECT_EQ(bad->type, TerminationType::kNoConvergence);
    EXPECT_EQ(bad->message, "Gauss-Newton step gave a non-finite cost");
  }
}

}  // namespace
}  // namespace carat
