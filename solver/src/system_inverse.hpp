#pragma once

// Internal: blocks of G = (H + diag(damping))^-1 for a LinearSystem just factorized. The whole
// system (SparseSystem) reads every block on its factor's pattern from the sparse inverse of the
// factor. The Schur complement (SchurSystem) reads the kept variables' blocks from the sparse
// inverse of S's factor (G restricted to them is S^-1), and an eliminated variable p's own block
// by back-substitution: G_pp = V^-1 + V^-1 (sum_ab W_a^T G_ab W_b) V^-1 over the kept variables
// a, b that share a block with p (such pairs share p, so they are on S's pattern). Any other
// block: one solve against the factorization per column.

#include <Eigen/Core>
#include <optional>

#include "linear_system.hpp"
#include "sparse_inverse.hpp"

namespace carat::internal {

class SchurSystem;
class SparseSystem;

class SystemInverse {
 public:
  /// `system` must have been factorized successfully, and stay so while this object is used.
  explicit SystemInverse(LinearSystem& system);

  /// G(a0 .. a0 + da, b0 .. b0 + db) at system offsets a0, b0 (each the start of a variable).
  Eigen::MatrixXd block(int a0, int da, int b0, int db);

  /// Whether block(a0, ., b0, .) needs no solve.
  bool on_pattern(int a0, int b0) const;

  /// For every system coordinate j, G(j, j), except at an eliminated variable's coordinates,
  /// where it is V^-1(j, j) (a lower bound of G(j, j): enough to test whether V is singular).
  Eigen::VectorXd diagonal_bound() const;

 private:
  Eigen::MatrixXd eliminated_block(int p);
  Eigen::MatrixXd solved_block(int a0, int da, int b0, int db);

  LinearSystem& system_;
  SchurSystem* schur_ = nullptr;
  std::optional<SparseInverse> inverse_;  // of the whole H, or of S (kept variables)
  int kept_size_ = 0;                     // coordinates in inverse_
  int cached_column_ = -1;                // b0 of the columns last solved for
  Eigen::MatrixXd cached_;                // G(:, b0 .. b0 + db)
};

}  // namespace carat::internal
