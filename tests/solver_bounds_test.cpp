// Holding part of a variable (SubsetManifold) and bounds on Euclidean coordinates, as Ceres users
// port them: the held coordinates never move, bounded ones end on their bound when the
// unconstrained optimum lies beyond it, with the rest at their constrained optimum.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solve.hpp"
#include "carat/solver/subset_manifold.hpp"
#include "curve_fit_problem.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using test::curve_data;
using test::ExpResidual;

TEST(SubsetManifoldTest, HeldCoordinatesNeverMoveAndTheRestMoveAsTheBase) {
  // Over R^3 holding coordinate 1: plus adds the step to coordinates 0 and 2.
  const SubsetManifold euclidean(3, {1});
  EXPECT_EQ(euclidean.ambient_size(), 3);
  EXPECT_EQ(euclidean.tangent_size(), 2);
  const double x[] = {1.0, 2.0, 3.0}, delta[] = {0.5, -1.0};
  double y[3];
  euclidean.plus(x, delta, y);
  EXPECT_EQ(y[0], 1.5);
  EXPECT_EQ(y[1], 2.0);
  EXPECT_EQ(y[2], 2.0);
  double back[2];
  euclidean.minus(y, x, back);
  EXPECT_EQ(back[0], 0.5);
  EXPECT_EQ(back[1], -1.0);
  // Over SE(3) holding roll and pitch (tangent 0 and 1): its plus_jacobian is the base's columns
  // 2..5, and plus agrees with the base's plus of the expanded step.
  const SubsetManifold yaw_and_position(se3_manifold(), {0, 1});
  double T[7];
  se3::Vector6d xi;
  xi << 0.3, -0.2, 0.7, 1.0, 2.0, 3.0;
  se3::to_storage(se3::exp(xi), T);
  double P[7 * 4], P_base[7 * 6];
  yaw_and_position.plus_jacobian(T, P);
  se3_manifold()->plus_jacobian(T, P_base);
  for (int i = 0; i < 7; ++i) {
    for (int k = 0; k < 4; ++k) EXPECT_EQ(P[i * 4 + k], P_base[i * 6 + k + 2]);
  }
  const double step[] = {0.1, 0.2, 0.3, 0.4}, full_step[] = {0.0, 0.0, 0.1, 0.2, 0.3, 0.4};
  double a[7], b[7];
  yaw_and_position.plus(T, step, a);
  se3_manifold()->plus(T, full_step, b);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(a[i], b[i]);
  EXPECT_STREQ(yaw_and_position.name(), "subset(se3)");
  // Bad coordinates.
  EXPECT_EQ(test::error_of([] { SubsetManifold(3, {3}); }),
            "SubsetManifold: coordinate 3 is out of range (euclidean has 3 tangent coordinates)");
  EXPECT_EQ(test::error_of([] {
              SubsetManifold(3, {1, 1});
            }),
            "SubsetManifold: coordinate 1 is held twice");
  EXPECT_EQ(test::error_of([] {
              SubsetManifold(2, {0, 1});
            }),
            "SubsetManifold: every coordinate of euclidean is held; hold a whole variable with "
            "Problem::set_constant()");
}

/// The curve fit y = exp(m x + c) over (m, c), 2,000 rows, from (0, 0), with a given manifold.
Problem curve(std::shared_ptr<const Manifold> manifold, const Eigen::Vector2d& start) {
  Problem problem;
  const VariableId mc = problem.add_variable(manifold, std::span<const double>(start.data(), 2));
  if (manifold->tangent_size() == 2) {
    problem.add_residual_block(
        make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, curve_data(2000, 1)), {mc});
  } else {
    problem.add_residual_block(
        make_autodiff_block<1, VariableSize<2, 1>>(ExpResidual{}, curve_data(2000, 1), {manifold}),
        {mc});
  }
  return problem;
}

TEST(SubsetManifoldTest, AHeldCoordinateStaysWhileTheOtherIsFitted) {
  // c held at 0.1 (its true value): m alone is fitted, near 0.3.
  Problem problem =
      curve(std::make_shared<SubsetManifold>(2, std::vector<int>{1}), Eigen::Vector2d(0.0, 0.1));
  const SolverSummary s = solve(SolverOptions{}, problem);
  ASSERT_EQ(s.termination, TerminationType::kConvergence) << s.message;
  EXPECT_EQ(problem.value(VariableId{0})[1], 0.1);
  EXPECT_NEAR(problem.value(VariableId{0})[0], 0.3, 2e-3);
  EXPECT_EQ(s.num_tangent_parameters, 1);
}

TEST(BoundsTest, ACoordinateEndsOnItsBoundAndTheRestAtTheirConstrainedOptimum) {
  Problem free = curve(euclidean_manifold(2), Eigen::Vector2d(0.0, 0.0));
  ASSERT_EQ(solve(SolverOptions{}, free).termination, TerminationType::kConvergence);
  const double m_free = free.value(VariableId{0})[0];
  ASSERT_GT(m_free, 0.29);
  // m <= 0.25, below the free optimum: m ends on the bound, c at its optimum for that m.
  Problem bounded = curve(euclidean_manifold(2), Eigen::Vector2d(0.0, 0.0));
  bounded.set_upper_bound(VariableId{0}, 0, 0.25);
  bounded.set_lower_bound(VariableId{0}, 1, -5.0);
  EXPECT_EQ(bounded.upper_bound(VariableId{0}, 0), 0.25);
  EXPECT_EQ(bounded.upper_bound(VariableId{0}, 1), std::numeric_limits<double>::infinity());
  SolverOptions options;
  options.gradient_tolerance = 1e-9;
  const SolverSummary s = solve(options, bounded);
  ASSERT_TRUE(s.is_solution_usable()) << s.message;
  EXPECT_EQ(bounded.value(VariableId{0})[0], 0.25);
  // The free coordinate's gradient vanishes; the bounded one's pushes against its bound.
  const ProblemEvaluation at = evaluate_problem(bounded);
  EXPECT_LT(std::abs(at.gradient[1]), 1e-6 * std::abs(at.gradient[0]));
  EXPECT_LT(at.gradient[0], 0.0);
  // c moved to make up for m: above its free value.
  EXPECT_GT(bounded.value(VariableId{0})[1], free.value(VariableId{0})[1]);
}

TEST(BoundsTest, BadBoundsAreErrorsNamingTheVariableAndCoordinate) {
  Problem problem = curve(euclidean_manifold(2), Eigen::Vector2d(0.0, 0.0));
  const VariableId mc{0};
  problem.set_upper_bound(mc, 0, 1.0);
  EXPECT_EQ(test::error_of([&] { problem.set_lower_bound(mc, 0, 2.0); }),
            "Problem::set_lower_bound: variable 0, coordinate 0: the lower bound 2 is above the "
            "upper bound 1");
  EXPECT_EQ(test::error_of([&] { problem.set_lower_bound(mc, 1, 0.5); }),
            "Problem::set_lower_bound: variable 0, coordinate 1: the value 0 is below the bound "
            "0.5");
  EXPECT_EQ(test::error_of([&] { problem.set_upper_bound(mc, 2, 1.0); }),
            "Problem::set_upper_bound: variable 0 (euclidean): coordinate 2 is out of range (2 "
            "coordinates)");
  EXPECT_EQ(test::error_of(
                [&] { problem.set_lower_bound(mc, 0, std::numeric_limits<double>::quiet_NaN()); }),
            "Problem::set_lower_bound: variable 0, coordinate 0: the bound nan is not a number "
            "below +inf");
  const VariableId pose = problem.add_se3(Eigen::Isometry3d::Identity());
  EXPECT_EQ(test::error_of([&] { problem.set_upper_bound(pose, 4, 1.0); }),
            "Problem::set_upper_bound: variable 1 (se3): bounds apply to Euclidean coordinates "
            "only");
  // A value moved outside its bounds after they were set: the solve refuses to start.
  problem.mutable_value(mc)[0] = 3.0;
  const SolverSummary s = solve(SolverOptions{}, problem);
  EXPECT_EQ(s.termination, TerminationType::kFailure);
  EXPECT_EQ(s.message,
            "the initial value is outside the bounds: variable 0, coordinate 0: the value 3 is "
            "outside its bounds [-inf, 1]");
}

}  // namespace
}  // namespace carat
