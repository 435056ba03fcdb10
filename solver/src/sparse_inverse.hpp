#pragma once

// Internal: the entries of A^-1 on the pattern of A's supernodal Cholesky factor (the sparse
// inverse subset, Takahashi et al.): every diagonal entry and every (i, j) where the factor holds
// L(i, j) or L(j, i). It is computed from the factor alone, supernode by supernode from the root
// down, in about the flops of one numeric factorization, and stored in the factor's own layout.
//
// For a supernode with columns S and rows R below them, L = [L_D; L_B] in those rows:
//   Z(R, S) = -Z(R, R) Y and Z(S, S) = (L_D L_D^T)^-1 - Y^T Z(R, S), with Y = L_B L_D^-1;
// Z(R, R) lies on the pattern of later supernodes (the rows of a supernode form a clique in the
// filled graph), so one pass from the last supernode to the first fills it all.

#include <cstddef>
#include <cstdint>
#include <vector>

struct cholmod_factor_struct;

namespace carat::internal {

class SparseInverse {
 public:
  /// Computes the subset from a numeric supernodal LL^T factor of A (CHOLMOD, 64-bit indices,
  /// any fill-reducing permutation). Throws carat::Error if the factor is not of that kind or its
  /// pattern is not closed (which a CHOLMOD factor always is).
  explicit SparseInverse(const cholmod_factor_struct& L);

  /// Order n of A.
  std::size_t size() const { return n_; }

  /// Whether A^-1(i, j) is on the factor's pattern (i, j in A's own indices).
  bool has(std::size_t i, std::size_t j) const;

  /// A^-1(i, j) for an entry on the pattern; throws carat::Error otherwise.
  double operator()(std::size_t i, std::size_t j) const;

  /// out (rows x cols, column-major) = A^-1(i0 .. i0 + rows, j0 .. j0 + cols); false (out
  /// untouched or partly written) if an entry is not on the pattern.
  bool block(std::size_t i0, int rows, std::size_t j0, int cols, double* out) const;

 private:
  /// Position of entry (r, c), r >= c in the factor's order, in z_; -1 if not on the pattern.
  std::int64_t position(std::size_t r, std::size_t c) const;

  std::size_t n_ = 0;
  std::vector<std::int64_t> super_, pi_, px_, rows_;  // copies of the factor's pattern
  std::vector<std::int64_t> column_super_;            // supernode of each column
  std::vector<std::int64_t> inverse_perm_;            // A's index -> factor's order
  std::vector<double> z_;                             // A^-1 in the factor's layout
};

}  // namespace carat::internal
