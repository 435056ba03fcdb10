// The Levenberg-Marquardt trust region on its own: the damping it asks for, which gain ratios
// it accepts, Nielsen's growth after an accepted step and the doubling shrink after rejections;
// the Gauss-Newton phase at the start; and the clamped diagonal and Gauss-Newton damping factors
// both methods build on.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../solver/src/hessian_damping.hpp"
#include "../solver/src/step_quality.hpp"
#include "../solver/src/trust_region_strategy.hpp"
#include "carat/solver/solver_options.hpp"

namespace carat {
namespace {

using internal::StepQuality;
using internal::TrustRegionStrategy;

/// A judged step with the given gain ratio and a finite trial cost.
StepQuality step_with_ratio(double gain_ratio) {
  StepQuality step;
  step.gain_ratio = gain_ratio;
  step.measured_ratio = gain_ratio;
  step.cost_is_finite = true;
  return step;
}

TEST(TrustRegionStrategyTest, StartsAtTheInitialRadius) {
  SolverOptions options;
  options.initial_trust_region_radius = 123.5;
  const TrustRegionStrategy region(options);
  EXPECT_EQ(region.radius(), 123.5);
  EXPECT_EQ(region.shrink_factor(), 2.0);
}

TEST(TrustRegionStrategyTest, RejectionsInARowDivideByTwoThenFourThenEight) {
  SolverOptions options;
  options.initial_trust_region_radius = 1e4;
  TrustRegionStrategy region(options);
  region.on_rejected();
  EXPECT_EQ(region.radius(), 5000.0);
  region.on_rejected();
  EXPECT_EQ(region.radius(), 1250.0);
  region.on_rejected();
  EXPECT_EQ(region.radius(), 156.25);
  EXPECT_EQ(region.shrink_factor(), 16.0);
}

TEST(TrustRegionStrategyTest, AnAcceptedStepResetsTheShrinkFactor) {
  SolverOptions options;
  options.initial_trust_region_radius = 1e4;
  options.max_trust_region_growth = 10.0;  // as solve() resolves it for the whole system
  TrustRegionStrategy region(options);
  region.on_rejected();
  region.on_rejected();
  ASSERT_EQ(region.radius(), 1250.0);
  // Gain ratio 1/2: 1 - (2 rho - 1)^3 = 1, the radius stays.
  region.on_accepted(0.5);
  EXPECT_EQ(region.radius(), 1250.0);
  EXPECT_EQ(region.shrink_factor(), 2.0);
  region.on_rejected();
  EXPECT_EQ(region.radius(), 625.0);
}

TEST(TrustRegionStrategyTest, AcceptedStepsGrowTheRadiusByNielsensRule) {
  SolverOptions options;
  options.initial_trust_region_radius = 9000.0;
  options.max_trust_region_growth = 4.0;
  TrustRegionStrategy region(options);
  // rho = 1/4: divisor 1 - (-1/2)^3 = 9/8, so the radius shrinks to 8000.
  region.on_accepted(0.25);
  EXPECT_EQ(region.radius(), 8000.0);
  // rho = 0: divisor 2.
  region.on_accepted(0.0);
  EXPECT_EQ(region.radius(), 4000.0);
  // rho = 3/4: divisor 7/8.
  region.on_accepted(0.75);
  EXPECT_DOUBLE_EQ(region.radius(), 4000.0 / 0.875);
  // rho = 1 and above: the divisor is held at 1 / max_trust_region_growth.
  region.on_accepted(1.0);
  EXPECT_DOUBLE_EQ(region.radius(), 4.0 * 4000.0 / 0.875);
  region.on_accepted(7.0);
  EXPECT_DOUBLE_EQ(region.radius(), 16.0 * 4000.0 / 0.875);
}

TEST(TrustRegionStrategyTest, GrowthStopsAtTheMaximumRadius) {
  SolverOptions options;
  options.initial_trust_region_radius = 1e4;
  options.max_trust_region_radius = 2.5e4;
  options.max_trust_region_growth = 10.0;
  TrustRegionStrategy region(options);
  region.on_accepted(1.0);
  EXPECT_EQ(region.radius(), 2.5e4);
  region.on_accepted(1.0);
  EXPECT_EQ(region.radius(), 2.5e4);
}

TEST(TrustRegionStrategyTest, AcceptsOnlyGainRatiosAboveTheMinimumWithAFiniteCost) {
  SolverOptions options;
  options.min_relative_decrease = 1e-3;
  const TrustRegionStrategy region(options);
  EXPECT_FALSE(region.accepts(step_with_ratio(1e-3)));
  EXPECT_TRUE(region.accepts(step_with_ratio(std::nextafter(1e-3, 1.0))));
  EXPECT_FALSE(region.accepts(step_with_ratio(-1.0)));
  EXPECT_FALSE(region.accepts(step_with_ratio(std::numeric_limits<double>::quiet_NaN())));
  StepQuality infinite_cost = step_with_ratio(2.0);
  infinite_cost.cost_is_finite = false;
  EXPECT_FALSE(region.accepts(infinite_cost));
  // The decision reads the gain ratio (1 for a step below the cost's rounding), not the measured
  // one.
  StepQuality below_rounding = step_with_ratio(1.0);
  below_rounding.measured_ratio = -3.0;
  below_rounding.below_rounding = true;
  EXPECT_TRUE(region.accepts(below_rounding));
}

TEST(TrustRegionStrategyTest, DampingIsTheClampedDiagonalOverTheRadius) {
  SolverOptions options;
  options.initial_trust_region_radius = 1e4;
  options.min_lm_diagonal = 1e-6;
  options.max_lm_diagonal = 1e32;
  TrustRegionStrategy region(options);
  const Eigen::Vector4d diagonal(0.0, 2.0, 1e40, -3.0);
  Eigen::VectorXd damping;
  region.damping(diagonal, &damping);
  ASSERT_EQ(damping.size(), 4);
  EXPECT_EQ(damping[0], 1e-6 / 1e4);
  EXPECT_EQ(damping[1], 2.0 / 1e4);
  EXPECT_EQ(damping[2], 1e32 / 1e4);
  EXPECT_EQ(damping[3], 1e-6 / 1e4);
  region.on_rejected();
  region.damping(diagonal, &damping);
  EXPECT_EQ(damping[1], 2.0 / 5000.0);
}

TEST(TrustRegionStrategyTest, GaussNewtonPhaseHoldsTheLargestRadiusWhileStepsGainEnough) {
  SolverOptions options;
  options.lm_start = LmStart::kGaussNewton;
  options.initial_trust_region_radius = 1e4;
  options.gauss_newton_phase_radius = 1e12;
  options.max_trust_region_growth = 10.0;
  options.gauss_newton_phase_min_gain = 0.5;
  TrustRegionStrategy region(options);
  EXPECT_TRUE(region.in_gauss_newton_phase());
  EXPECT_EQ(region.radius(), 1e12);
  region.on_accepted(0.5);  // at the threshold: the phase goes on, the radius stays
  region.on_accepted(1.7);
  EXPECT_TRUE(region.in_gauss_newton_phase());
  EXPECT_EQ(region.radius(), 1e12);
  // Below the threshold (the step itself is taken): LM from the initial radius, as at a start.
  region.on_accepted(0.3);
  EXPECT_FALSE(region.in_gauss_newton_phase());
  EXPECT_EQ(region.radius(), 1e4);
  EXPECT_EQ(region.shrink_factor(), 2.0);
  // Afterwards the ordinary rules: Nielsen's growth, the doubling shrink.
  region.on_accepted(1.0);
  EXPECT_EQ(region.radius(), 1e5);
  region.on_rejected();
  EXPECT_EQ(region.radius(), 5e4);
}

TEST(TrustRegionStrategyTest, ARejectionEndsTheGaussNewtonPhaseAtTheInitialRadius) {
  SolverOptions options;
  options.lm_start = LmStart::kGaussNewton;
  options.initial_trust_region_radius = 1e4;
  TrustRegionStrategy region(options);
  region.on_rejected();
  EXPECT_FALSE(region.in_gauss_newton_phase());
  // Exactly where a solve that started at the initial radius stands before its first step.
  EXPECT_EQ(region.radius(), 1e4);
  EXPECT_EQ(region.shrink_factor(), 2.0);
  region.on_rejected();
  EXPECT_EQ(region.radius(), 5000.0);
  // kTrustRegion (and the unresolved kAuto) start at the initial radius with no phase.
  options.lm_start = LmStart::kTrustRegion;
  EXPECT_FALSE(TrustRegionStrategy(options).in_gauss_newton_phase());
  EXPECT_EQ(TrustRegionStrategy(options).radius(), 1e4);
}

TEST(HessianDampingTest, ClampsEveryEntryToTheSetRange) {
  SolverOptions options;
  options.min_lm_diagonal = 0.5;
  options.max_lm_diagonal = 8.0;
  const Eigen::VectorXd clamped =
      internal::clamped_hessian_diagonal(Eigen::Vector4d(0.25, 0.5, 3.0, 100.0), options);
  EXPECT_EQ(clamped, Eigen::Vector4d(0.5, 0.5, 3.0, 8.0));
}

TEST(HessianDampingTest, GaussNewtonStartsUndampedAndGrowsByAHundredUpToOne) {
  const std::vector<double>& factors = internal::gauss_newton_damping_factors();
  ASSERT_EQ(factors.size(), 8u);
  EXPECT_EQ(factors[0], 0.0);
  EXPECT_EQ(factors[1], 1e-12);
  for (std::size_t k = 2; k < factors.size(); ++k) EXPECT_EQ(factors[k], factors[k - 1] * 100.0);
  EXPECT_LE(factors.back(), 1.0);
  EXPECT_GT(factors.back() * 100.0, 1.0);
}

}  // namespace
}  // namespace carat
