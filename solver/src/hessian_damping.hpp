#pragma once

// Internal: the damping added to the normal equations. Both methods scale it by diag(H),
// clamped so that a zero or huge diagonal entry still gives a usable, bounded damping.

#include <Eigen/Core>
#include <vector>

#include "carat/solver/solver_options.hpp"

namespace carat::internal {

/// diag(H) clamped to [options.min_lm_diagonal, options.max_lm_diagonal], element by element.
Eigen::VectorXd clamped_hessian_diagonal(const Eigen::VectorXd& hessian_diagonal,
                                         const SolverOptions& options);

/// The factors Gauss-Newton tries, in order, until the system factorizes: 0 (undamped), then
/// 1e-12, each next one 100 times larger while it stays <= 1. Each multiplies the clamped diag(H).
const std::vector<double>& gauss_newton_damping_factors();

}  // namespace carat::internal
