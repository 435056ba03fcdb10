#pragma once

// Internal: the linear system of one solver iteration, (H + diag(damping)) delta = rhs, behind
// one interface: sparse Cholesky of the whole system (SparseSystem) or the Schur complement
// that eliminates a group of variables first (SchurSystem). make_linear_system() picks one.

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "huge_pages.hpp"

namespace carat::internal {

/// Per-block linearization storage for every block: H (D x D, symmetric; its lower triangle
/// packed by columns, column c holding rows c..D-1: D (D + 1) / 2 numbers) and b (D).
struct BlockLinearizations {
  std::vector<std::size_t> h_offset;  ///< start of block i's packed H in h
  std::vector<std::size_t> b_offset;  ///< start of block i's b in b
  std::vector<int> dim;               ///< D of block i
  HugeVector<double> h;               ///< all blocks' H
  HugeVector<double> b;               ///< all blocks' b
  std::vector<double> cost;           ///< 1/2 rho(s) per block
};

/// Offset of column c in a D x D lower triangle packed by columns.
inline std::size_t packed_column(std::size_t D, std::size_t c) { return c * (2 * D - c + 1) / 2; }

/// out(r, c) += H(row0 + r, col0 + c) for r < rows, c < cols (out column-major, leading
/// dimension ld), H packed as above; the row and column ranges are the same variable's
/// (the whole block is added) or two different variables' (disjoint ranges).
inline void add_packed_block(const double* H, std::size_t D, std::size_t row0, std::size_t col0,
                             int rows, int cols, double* out, std::size_t ld) {
  const auto R = static_cast<std::size_t>(rows);
  const auto C = static_cast<std::size_t>(cols);
  if (row0 > col0) {  // below the diagonal: each column is contiguous
    for (std::size_t c = 0; c < C; ++c) {
      const double* src = H + packed_column(D, col0 + c) + (row0 - col0 - c);
      for (std::size_t r = 0; r < R; ++r) out[c * ld + r] += src[r];
    }
  } else if (row0 < col0) {  // above: H(i, j) = H(j, i), rows of the lower triangle
    for (std::size_t r = 0; r < R; ++r) {
      const double* src = H + packed_column(D, row0 + r) + (col0 - row0 - r);
      for (std::size_t c = 0; c < C; ++c) out[c * ld + r] += src[c];
    }
  } else {  // a diagonal block, both triangles
    for (std::size_t c = 0; c < C; ++c) {
      const double* src = H + packed_column(D, col0 + c);
      out[c * ld + c] += src[0];
      for (std::size_t r = c + 1; r < R; ++r) {
        out[c * ld + r] += src[r - c];
        out[r * ld + c] += src[r - c];
      }
    }
  }
}

class LinearSystem {
 public:
  virtual ~LinearSystem() = default;

  /// Scalar size n of the system (tangent dimensions of the free variables).
  int size() const { return n_; }
  /// Tangent offset of each variable in the system, -1 for constant variables.
  const std::vector<int>& variable_offset() const { return var_offset_; }
  /// Stored nonzeros of the matrix that is factorized (lower triangle).
  virtual std::size_t hessian_nonzeros() const = 0;
  /// Nonzeros of the Cholesky factor.
  virtual std::size_t factor_nonzeros() const = 0;
  /// Name of the factorization and ordering for reports.
  const std::string& description() const { return description_; }

  /// Gathers blocks' H and b into the undamped system and the gradient (deterministic).
  virtual void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) = 0;

  /// Undamped diagonal of H.
  virtual Eigen::VectorXd diagonal() const = 0;

  /// Factorizes H + diag(damping) numerically; false if not positive definite.
  virtual bool factorize(const Eigen::VectorXd& damping) = 0;

  /// y = H x with the undamped values of the last assembly.
  virtual void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const = 0;

  /// Solves (H + diag(damping)) x = rhs with the last successful factorization (which may be
  /// of an earlier assembly).
  virtual void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) = 0;

  /// Seconds spent eliminating variables (forming the reduced system, back-substitution)
  /// since the last call; 0 for the whole-system path.
  virtual double take_elimination_seconds() { return 0.0; }

 protected:
  int n_ = 0;
  std::vector<int> var_offset_;
  std::string description_;
};

/// The system for `problem` under `options` (linear_solver, ordering). Throws carat::Error when
/// the Schur complement is asked for and no valid group of variables can be eliminated.
std::unique_ptr<LinearSystem> make_linear_system(const Problem& problem,
                                                 const SolverOptions& options);

}  // namespace carat::internal
