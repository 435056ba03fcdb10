// The tests that end a solve, each on its own: which one fires at its boundary, with which
// termination type and message.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "../solver/src/stop_criteria.hpp"
#include "carat/solver/solver_summary.hpp"

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

/// A summary whose every field differs from `base`'s by `k` (two rows of iterations).
SolverSummary numbered_summary(int k) {
  SolverSummary s;
  s.termination = k == 1 ? TerminationType::kNoConvergence : TerminationType::kConvergence;
  s.message = "solve " + std::to_string(k);
  s.initial_cost = 100.0 * k;
  s.final_cost = 10.0 * k;
  s.num_iterations = 2;
  s.num_successful_steps = 1 * k;
  s.num_unsuccessful_steps = 2 * k;
  s.num_reused_factorizations = 3 * k;
  s.num_refused_reuses = 4 * k;
  s.num_linear_solver_failures = 5 * k;
  s.num_variables = 6 * k;
  s.num_free_variables = 7 * k;
  s.num_tangent_parameters = 8 * k;
  s.num_residual_blocks = 9 * k;
  s.num_residual_rows = 10u * static_cast<std::size_t>(k);
  s.factor_nonzeros = 11u * static_cast<std::size_t>(k);
  s.hessian_nonzeros = 12u * static_cast<std::size_t>(k);
  s.residual_memory_bytes = 13u * static_cast<std::size_t>(k);
  s.num_threads = k;
  s.method = "method " + std::to_string(k);
  s.linear_solver = "linear solver " + std::to_string(k);
  s.trust_region_growth = 1.5 * k;
  s.time = {0.1 * k, 0.2 * k, 0.3 * k, 0.4 * k, 0.5 * k, 0.6 * k, 0.7 * k, 1.0 * k};
  for (int i = 0; i < 2; ++i) {
    IterationSummary row;
    row.iteration = i;
    row.cost = 1.0 * k + i;
    row.cumulative_time_s = 0.25 * k * (i + 1);
    s.iterations.push_back(row);
  }
  return s;
}

TEST(SolverSummaryTest, MergingALaterSolveSumsCountsAndTimesAndKeepsItsEndState) {
  SolverSummary total = numbered_summary(1);
  const SolverSummary later = numbered_summary(2);
  merge_later_solve(total, later);
  // Summed.
  EXPECT_EQ(total.num_iterations, 4);
  EXPECT_EQ(total.num_successful_steps, 3);
  EXPECT_EQ(total.num_unsuccessful_steps, 6);
  EXPECT_EQ(total.num_reused_factorizations, 9);
  EXPECT_EQ(total.num_refused_reuses, 12);
  EXPECT_EQ(total.num_linear_solver_failures, 15);
  const double times[] = {total.time.linearize_s, total.time.cost_s,    total.time.assembly_s,
                          total.time.symbolic_s,  total.time.numeric_s, total.time.solve_s,
                          total.time.schur_s};
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(times[i], 0.3 * (i + 1), 1e-15) << "stage " << i;
  EXPECT_NEAR(total.time.total_s, 3.0, 1e-15);
  // The first solve's start, the later one's end state, problem and setup.
  EXPECT_EQ(total.initial_cost, 100.0);
  EXPECT_EQ(total.final_cost, 20.0);
  EXPECT_EQ(total.termination, TerminationType::kConvergence);
  EXPECT_EQ(total.message, "solve 2");
  EXPECT_EQ(total.num_variables, 12);
  EXPECT_EQ(total.num_free_variables, 14);
  EXPECT_EQ(total.num_tangent_parameters, 16);
  EXPECT_EQ(total.num_residual_blocks, 18);
  EXPECT_EQ(total.num_residual_rows, 20u);
  EXPECT_EQ(total.factor_nonzeros, 22u);
  EXPECT_EQ(total.hessian_nonzeros, 24u);
  EXPECT_EQ(total.residual_memory_bytes, 26u);
  EXPECT_EQ(total.num_threads, 2);
  EXPECT_EQ(total.method, "method 2");
  EXPECT_EQ(total.linear_solver, "linear solver 2");
  EXPECT_EQ(total.trust_region_growth, 3.0);
  // Rows appended, numbered on, cumulative times continued.
  ASSERT_EQ(total.iterations.size(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(total.iterations[static_cast<std::size_t>(i)].iteration, i);
  EXPECT_EQ(total.iterations[2].cost, 2.0);
  EXPECT_NEAR(total.iterations[2].cumulative_time_s, 0.5 + 0.5, 1e-15);
  EXPECT_NEAR(total.iterations[3].cumulative_time_s, 0.5 + 1.0, 1e-15);
}

TEST(SolverSummaryTest, MergingIntoAnEmptySummaryTakesTheLaterSolve) {
  SolverSummary total;
  merge_later_solve(total, numbered_summary(3));
  EXPECT_EQ(total.initial_cost, 300.0);
  EXPECT_EQ(total.num_iterations, 2);
  EXPECT_EQ(total.iterations.size(), 2u);
  EXPECT_EQ(total.message, "solve 3");
}

}  // namespace
}  // namespace carat
