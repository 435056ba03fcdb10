#pragma once

// Internal: a LinearSystem over a given symmetric matrix A (a copy of its lower triangle in
// compressed columns) rather than over a problem's blocks: factorize A + diag(damping) with
// CHOLMOD (supernodal, AMD ordering), solve, multiply. The covariance runs its gauge search on
// the Schur complement S this way, after the Schur system has formed S once.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "cholmod_session.hpp"
#include "linear_system.hpp"

namespace carat::internal {

class SymmetricMatrixSystem final : public LinearSystem {
 public:
  /// A (n x n) from its lower triangle: colptr (n + 1), rows and values (sorted within columns,
  /// the diagonal present in every column). Runs CHOLMOD's symbolic analysis.
  SymmetricMatrixSystem(int n, std::vector<std::int64_t> colptr, std::vector<std::int64_t> rows,
                        std::vector<double> values);
  ~SymmetricMatrixSystem() override;

  std::size_t hessian_nonzeros() const override { return rows_.size(); }
  std::size_t factor_nonzeros() const override;
  double factor_flops() const override;
  /// Not available: A is given. Throws carat::Error.
  void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) override;
  Eigen::VectorXd diagonal() const override;
  bool factorize(const Eigen::VectorXd& damping) override;
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const override;
  void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) override;

  /// The CHOLMOD session: after factorize(), its factor is of A + diag(damping).
  CholmodSession& cholmod() { return *cholmod_; }

 private:
  std::vector<std::int64_t> colptr_, rows_, diag_pos_;
  std::vector<double> values_;    // A
  std::vector<double> factored_;  // A + diag(damping): what CHOLMOD's matrix points at
  std::unique_ptr<CholmodSession> cholmod_;
};

}  // namespace carat::internal
