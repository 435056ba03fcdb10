// SE(2): Exp/Log round trips, the adjoint and the right Jacobian against central differences,
// the manifold's plus/minus/plus_jacobian and heading wrap, and Problem's SE(2) accessors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "carat/base/error.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/se2.hpp"

namespace carat {
namespace {

constexpr double kPi = std::numbers::pi;

Eigen::Vector3d random_tangent(std::mt19937_64& rng, double rotation, double shift) {
  std::normal_distribution<double> normal;
  return {rotation * normal(rng), shift * normal(rng), shift * normal(rng)};
}

double pose_distance(const Eigen::Isometry2d& A, const Eigen::Isometry2d& B) {
  return se2::log(A.inverse() * B).cwiseAbs().maxCoeff();
}

TEST(SE2Test, WrapAngleKeepsHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(se2::wrap_angle(kPi), kPi);
  EXPECT_DOUBLE_EQ(se2::wrap_angle(-kPi), kPi);
  EXPECT_DOUBLE_EQ(se2::wrap_angle(3.0 * kPi), kPi);
  EXPECT_NEAR(se2::wrap_angle(2.0 * kPi + 0.25), 0.25, 1e-15);
  EXPECT_NEAR(se2::wrap_angle(-2.0 * kPi - 0.25), -0.25, 1e-15);
  EXPECT_EQ(se2::wrap_angle(0.0), 0.0);
}

TEST(SE2Test, ExpLogRoundTripAndJacobians) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    // Tiny angles exercise the series branch.
    const double rotation = trial % 5 == 0 ? 1e-6 : 1.0;
    Eigen::Vector3d xi = random_tangent(rng, rotation, 2.0);
    xi[0] = se2::wrap_angle(xi[0]);
    EXPECT_LT((se2::log(se2::exp(xi)) - xi).norm(), 1e-12);
    // Adjoint: T Exp(d) T^-1 = Exp(Ad d).
    const Eigen::Isometry2d T = se2::exp(random_tangent(rng, 1.0, 3.0));
    const Eigen::Vector3d d = random_tangent(rng, 0.3, 0.5);
    EXPECT_LT(pose_distance(T * se2::exp(d) * T.inverse(), se2::exp(se2::adjoint(T) * d)), 1e-12);
    // Right Jacobian and its inverse against central differences.
    const Eigen::Matrix3d J_r = se2::right_jacobian(xi);
    EXPECT_LT((J_r * se2::right_jacobian_inverse(xi) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    constexpr double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(k) * h;
      const Eigen::Vector3d numeric = (se2::log(se2::exp(xi).inverse() * se2::exp(xi + e)) -
                                       se2::log(se2::exp(xi).inverse() * se2::exp(xi - e))) /
                                      (2.0 * h);
      EXPECT_LT((numeric - J_r.col(k)).norm(), 1e-8) << "column " << k;
    }
  }
}

TEST(SE2Test, ManifoldPlusMinusAndJacobian) {
  std::mt19937_64 rng(8);
  const auto manifold = se2_manifold();
  EXPECT_STREQ(manifold->name(), "se2");
  for (int trial = 0; trial < 30; ++trial) {
    double x[3], y[3], delta[3], back[3];
    se2::to_storage(se2::exp(random_tangent(rng, 2.0, 3.0)), x);
    const Eigen::Vector3d d = random_tangent(rng, 0.8, 1.0);
    manifold->plus(x, d.data(), y);
    EXPECT_TRUE(manifold->is_valid(y));
    // x [+] d = x * Exp(d).
    EXPECT_LT(pose_distance(se2::from_storage(y), se2::from_storage(x) * se2::exp(d)), 1e-12);
    manifold->minus(y, x, delta);
    EXPECT_LT((Eigen::Map<Eigen::Vector3d>(delta) - d).norm(), 1e-12);
    manifold->plus(x, delta, back);
    EXPECT_LT(pose_distance(se2::from_storage(back), se2::from_storage(y)), 1e-12);
    double exact[9], numeric[9];
    manifold->plus_jacobian(x, exact);
    manifold->Manifold::plus_jacobian(x, numeric);
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(exact[k], numeric[k], 1e-8);
  }
  // Headings stay in (-pi, pi] across the cut.
  const double x[3] = {1.0, 2.0, kPi - 0.1};
  const double d[3] = {0.3, 0.0, 0.0};
  double y[3];
  manifold->plus(x, d, y);
  EXPECT_NEAR(y[2], -kPi + 0.2, 1e-14);
  const double outside[3] = {0.0, 0.0, 4.0};
  EXPECT_FALSE(manifold->is_valid(outside));
  const double not_finite[3] = {std::nan(""), 0.0, 0.0};
  EXPECT_FALSE(manifold->is_valid(not_finite));
}

TEST(SE2Test, ProblemStoresPlanarPoses) {
  Problem problem;
  const Eigen::Isometry2d T = se2::make(1.5, -2.0, 3.0);
  const VariableId v = problem.add_se2(T);
  EXPECT_STREQ(problem.manifold(v).name(), "se2");
  EXPECT_LT(pose_distance(problem.se2(v), T), 1e-15);
  problem.set_se2(v, se2::make(0.0, 1.0, -kPi));
  EXPECT_DOUBLE_EQ(problem.value(v)[2], kPi);
  const VariableId w = problem.add_euclidean(Eigen::Vector3d::Zero());
  try {
    (void)problem.se2(w);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "Problem::se2: variable 1 is not an SE(2) variable");
  }
}

}  // namespace
}  // namespace carat
