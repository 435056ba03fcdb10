// Anderson's method on a linear fixed-point map (it is GMRES there), and LM's accelerated tail on
// a problem whose Gauss-Newton iteration converges linearly.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <array>
#include <cmath>
#include <memory>
#include <span>

#include "../solver/src/anderson_acceleration.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/residual_block.hpp"
#include "carat/solver/solve.hpp"

namespace carat {
namespace {

/// An orthogonal 4 x 4 matrix from a fixed seed.
Eigen::Matrix4d rotation() {
  const Eigen::Matrix4d a = (Eigen::Matrix4d() << 0.3, -1.2, 0.7, 0.1,  //
                             0.9, 0.4, -0.2, 1.1,                       //
                             -0.5, 0.8, 1.3, -0.4,                      //
                             0.2, -0.6, 0.5, 0.9)
                                .finished();
  return Eigen::HouseholderQR<Eigen::Matrix4d>(a).householderQ();
}

TEST(AndersonAccelerationTest, SolvesALinearFixedPointMapInDimensionPlusOneSteps) {
  // x <- x + f(x), f(x) = -M^-1 (A x - b): M = diag(A) / 0.2 makes the plain iteration slow.
  const Eigen::Matrix4d q = rotation();
  const Eigen::Vector4d eig(1.0, 0.3, 0.1, 0.05);
  const Eigen::Matrix4d A = q * eig.asDiagonal() * q.transpose();
  const Eigen::Vector4d b(1.0, -2.0, 0.5, 3.0);
  const Eigen::Vector4d solution = A.ldlt().solve(b);
  const Eigen::Matrix4d M_inv = (A.diagonal() / 0.2).cwiseInverse().asDiagonal();
  const auto f = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd { return -M_inv * (A * x - b); };

  internal::AndersonAcceleration anderson(4);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(4);
  Eigen::VectorXd plain = x;
  EXPECT_FALSE(anderson.ready());
  for (int k = 0; k < 5; ++k) {
    const Eigen::VectorXd solved = f(x);
    Eigen::VectorXd step = solved;
    if (anderson.ready()) {
      ASSERT_TRUE(anderson.propose(solved, &step));
    }
    anderson.push(solved, step);
    x += step;
    plain += f(plain);
  }
  // Four pairs span the space: the fifth step lands on the solution.
  EXPECT_LT((x - solution).norm(), 1e-9 * solution.norm());
  EXPECT_GT((plain - solution).norm(), 0.3 * solution.norm());
  // After reset() nothing is proposed; memory 0 never proposes.
  anderson.reset();
  EXPECT_FALSE(anderson.ready());
  internal::AndersonAcceleration off(0);
  off.push(f(x), f(x));
  EXPECT_FALSE(off.ready());
}

/// r = [y_i + 1, l_i y_i^2 + y_i - 1] for y = Q x: the minimum is x = 0 with residuals +-1, where
/// J^T J is 2 and the Hessian 2 - 2 l_i along each y_i (the only minimum for l_i < 1/2), so
/// Gauss-Newton converges linearly with rate l_i (gain ratios near 2 - l_i) and Q mixes the slow
/// directions.
class LargeResidualBlock final : public ResidualBlock {
 public:
  int num_rows() const override { return 8; }
  std::span<const int> tangent_dims() const override { return dims_; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    const Eigen::Vector4d y = q_ * Eigen::Map<const Eigen::Vector4d>(params[0]);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const int i = rows[k] / 2;
      const bool second = rows[k] % 2 == 1;
      residuals[k] = second ? rate_[i] * y[i] * y[i] + y[i] - 1.0 : y[i] + 1.0;
      if (!jacobian) continue;
      const double scale = second ? 2.0 * rate_[i] * y[i] + 1.0 : 1.0;
      for (int c = 0; c < 4; ++c) jacobian[4 * k + c] = scale * q_(i, c);
    }
  }
  std::size_t memory_bytes() const override { return sizeof(*this); }

 private:
  std::array<int, 1> dims_{4};
  Eigen::Matrix4d q_ = rotation();
  std::array<double, 4> rate_{0.2, 0.3, 0.35, 0.4};
};

SolverSummary solve_large_residual(int anderson_memory, Eigen::Vector4d* x_out) {
  Problem problem;
  const Eigen::Vector4d y0(0.3, -0.3, 0.25, -0.2);
  const VariableId x = problem.add_euclidean(rotation().transpose() * y0);
  problem.add_residual_block(std::make_shared<LargeResidualBlock>(), {x});
  SolverOptions options;
  options.anderson_memory = anderson_memory;
  options.max_iterations = 500;
  options.function_tolerance = 1e-14;
  const SolverSummary summary = solve(options, problem);
  *x_out = Eigen::Map<const Eigen::Vector4d>(problem.value(x).data());
  return summary;
}

TEST(AndersonAccelerationTest, AnAcceleratedTailReachesTheSameMinimumInFewerIterations) {
  Eigen::Vector4d plain_x;
  const SolverSummary plain = solve_large_residual(0, &plain_x);
  Eigen::Vector4d fast_x;
  const SolverSummary fast = solve_large_residual(5, &fast_x);
  ASSERT_EQ(plain.termination, TerminationType::kConvergence) << plain.full_report();
  ASSERT_EQ(fast.termination, TerminationType::kConvergence) << fast.full_report();
  // The minimum: x = 0, cost 1/2 * 8 rows * 1.
  EXPECT_NEAR(fast.final_cost, 4.0, 1e-12);
  EXPECT_LE(fast.final_cost, plain.final_cost);
  EXPECT_LT(fast_x.norm(), 1e-6);
  EXPECT_EQ(plain.num_accelerated_steps, 0);
  EXPECT_GT(fast.num_accelerated_steps, 0);
  // Gauss-Newton's rate here is 0.4 at best (cost 0.16 per iteration): 16 iterations; Anderson's
  // steps lower the cost about a hundredfold each: 9.
  EXPECT_LE(fast.num_iterations + 5, plain.num_iterations)
      << fast.full_report() << plain.full_report();
  int flagged = 0;
  for (const IterationSummary& row : fast.iterations) flagged += row.accelerated ? 1 : 0;
  EXPECT_EQ(flagged, fast.num_accelerated_steps);
  EXPECT_NE(fast.full_report().find("accelerated)"), std::string::npos);
  EXPECT_NE(
      fast.to_json().find("\"accelerated_steps\":" + std::to_string(fast.num_accelerated_steps)),
      std::string::npos);
}

}  // namespace
}  // namespace carat
