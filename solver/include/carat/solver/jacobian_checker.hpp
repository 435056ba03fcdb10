#pragma once

/// Numeric-Jacobian checker for residual blocks, for users' own plugins as much as carat's:
/// central differences through each variable's manifold plus(), compared with the block's
/// analytic Jacobian J = J_r A.

#include <Eigen/Core>
#include <span>
#include <string>

#include "carat/solver/manifold.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// Step and tolerances of check_jacobians().
struct JacobianCheckOptions {
  double step = 1e-6;                ///< tangent step of the central differences
  double absolute_tolerance = 1e-6;  ///< allowed |J - J_numeric| per entry ...
  double relative_tolerance = 1e-6;  ///< ... plus this times max |J_numeric| of the block
};

/// What check_jacobians() found.
struct JacobianCheckResult {
  bool ok = false;             ///< every entry within tolerance and every value finite
  double max_abs_error = 0.0;  ///< max |J - J_numeric|
  double max_rel_error = 0.0;  ///< max_abs_error / max(1, max |J_numeric|)
  int worst_row = -1;          ///< row of the largest error
  int worst_col = -1;          ///< tangent column of the largest error
  Eigen::MatrixXd analytic;    ///< J = J_r A (N x D)
  Eigen::MatrixXd numeric;     ///< central-difference Jacobian (N x D)
  std::string message;         ///< one line: verdict and worst entry
};

/// Compares the block's analytic Jacobian at `params` with central differences taken through
/// `manifolds` (one per variable, in the block's order). The block is evaluated on every row.
JacobianCheckResult check_jacobians(const ResidualBlock& block,
                                    std::span<const Manifold* const> manifolds,
                                    ParameterPointers params,
                                    const JacobianCheckOptions& options = {});

/// The analytic full Jacobian J = J_r A (N x D) and residuals of every row at `params`.
void evaluate_full_jacobian(const ResidualBlock& block, ParameterPointers params,
                            Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian);

}  // namespace carat
