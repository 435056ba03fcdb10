#pragma once

// Dense references for the covariance tests: the Gauss-Newton Hessian of a problem built
// directly from its blocks' Jacobian rows, its inverse and its pseudo-inverse. Compiled once, in
// the test support library (the long-double eigensolvers are a slow compile).

#include <Eigen/Core>
#include <vector>

#include "carat/solver/problem.hpp"

namespace carat::test {

/// H over the free variables in variable order (offsets[v]: start of v, -1 when constant):
/// sum over blocks of J^T J with J = J_r A from every row, the loss applied as solve() applies
/// it (rho' J^T J + 2 rho'' (J^T r)(J^T r)^T where rho' + 2 s rho'' > 0, else rho' J^T J).
Eigen::MatrixXd dense_hessian(const Problem& problem, std::vector<int>* offsets);

/// The minimum-norm pseudo-inverse of a symmetric positive semi-definite H, treating the
/// `nullity` smallest eigenvalues as zero (in long double: the reference must be more exact than
/// the tested result, and H's condition number can reach 1e8).
Eigen::MatrixXd dense_pseudo_inverse(const Eigen::MatrixXd& H, int nullity);

/// The covariance under the gauge that makes the perturbation of the `kept` coordinates
/// orthogonal to H's free directions (the `nullity` smallest eigenvalues' eigenvectors N):
/// P H^+ P^T with P = I - N' M^T E^T, M an orthonormal basis of N's kept rows, N' = N T the
/// null vectors whose kept rows are M, E selecting the kept coordinates (long double).
Eigen::MatrixXd dense_kept_gauge(const Eigen::MatrixXd& H, int nullity,
                                 const std::vector<char>& kept);

/// H^-1 of a symmetric positive definite H (in long double, as above).
Eigen::MatrixXd dense_inverse(const Eigen::MatrixXd& H);

/// |A - B| / |B| (Frobenius).
double relative_error(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B);

}  // namespace carat::test
