#pragma once

// Internal: blocks of G = (H + diag(damping))^-1 for a linear system just factorized.
//
// The whole system (SparseSystem) reads every block on its factor's pattern from the sparse
// inverse of the factor and solves against it for any other (one solve per column).
//
// The Schur complement (SchurSystem) with H = [A B; B^T C], C block diagonal (one V_p per
// eliminated variable p, W_e its blocks with the kept variables): G restricted to the kept
// variables is S^-1, read the same way from a factor of S (the Schur system's own, or another
// one's of a modified S); every block with an eliminated variable follows from those by
// back-substitution, without a solve over the whole system:
//   G_pb = -V_p^-1 sum_e W_e^T G_{c(e), b}                          (b kept)
//   G_pq = delta_pq V_p^-1 + V_p^-1 (sum_{e of p, f of q} W_e^T G_{c(e), c(f)} W_f) V_q^-1
// over the edges e of p (c(e): the kept variable it shares a block with). For p == q the kept
// pairs share p, so they are on S's pattern: no solve at all.

#include <Eigen/Core>
#include <optional>

#include "cholmod_session.hpp"
#include "linear_system.hpp"
#include "sparse_inverse.hpp"

namespace carat::internal {

class SchurSystem;
class SparseSystem;

class SystemInverse {
 public:
  /// The whole system, factorized successfully (and staying so while this object is used).
  explicit SystemInverse(SparseSystem& sparse);
  /// The Schur complement: kept blocks from `kept`'s factor (of S with any damping; n x n for
  /// the Schur system's reduced size n), eliminated ones from `schur`'s V^-1 of its last
  /// factorization and its W.
  SystemInverse(const SchurSystem& schur, CholmodSession& kept);

  /// G(a0 .. a0 + da, b0 .. b0 + db) at system offsets a0, b0 (each the start of a variable).
  Eigen::MatrixXd block(int a0, int da, int b0, int db);

  /// From now on the kept variables' blocks are those of P G P^T, P = I - N N^T over the kept
  /// coordinates (N: orthonormal free directions, Q = G N, K = N^T G N; kept size x k), and the
  /// eliminated variables' follow from them by the same back-substitution: the covariance under
  /// the gauge that makes the kept variables' perturbation orthogonal to N (H^+ without a Schur
  /// complement).
  void remove_free_directions(Eigen::MatrixXd N, Eigen::MatrixXd Q, Eigen::MatrixXd K);

  /// Whether block(a0, ., b0, .) needs no solve.
  bool on_pattern(int a0, int b0) const;

  /// For every system coordinate j, G(j, j), except at an eliminated variable's coordinates,
  /// where it is V^-1(j, j) (a lower bound of G(j, j): enough to test whether V is singular).
  Eigen::VectorXd diagonal_bound() const;

  /// Coordinates of the kept variables (the whole system's size without a Schur complement).
  int kept_size() const { return kept_size_; }

 private:
  Eigen::MatrixXd kept_block(int a0, int da, int b0, int db);
  Eigen::MatrixXd solved_block(int a0, int da, int b0, int db);
  /// sum over p's edges e of W_e^T G_{c(e), b}: dp x db.
  Eigen::MatrixXd edges_times_kept(int p, int b0, int db);

  const SchurSystem* schur_ = nullptr;
  CholmodSession& kept_;
  std::optional<SparseInverse> inverse_;  // of the whole H, or of S (kept variables)
  int kept_size_ = 0;
  int cached_column_ = -1;     // b0 of the kept columns last solved for
  Eigen::MatrixXd cached_;     // G(kept, b0 .. b0 + db)
  Eigen::MatrixXd N_, Q_, K_;  // free directions removed (none: 0 columns)
};

/// Rows of an eliminated variable p in `X` lifted from the kept rows: -V_p^-1 sum_e W_e^T
/// X(c(e) rows) (a null vector of H from one of S, when X is one), with `schur`'s last V^-1.
Eigen::MatrixXd lift_eliminated(const SchurSystem& schur, int p, const Eigen::MatrixXd& X_kept);

}  // namespace carat::internal
