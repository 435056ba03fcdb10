#include "elimination.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "simd.hpp"

namespace carat::internal {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// y -= a * x over n contiguous doubles (vectorizes: no reduction).
CARAT_MULTIVERSION
void axpy_minus(double* __restrict y, const double* __restrict x, double a, Eigen::Index n) {
  for (Eigen::Index i = 0; i < n; ++i) y[i] -= a * x[i];
}

/// Gauss-Jordan with partial pivoting on the row-major m x n matrix T (in place): column by
/// column, a pivot above `tolerance` becomes a unit pivot row and is cleared from every other
/// row; a column without one is free. Only the columns a later step still reads are updated.
CARAT_MULTIVERSION
void gauss_jordan(RowMatrix& T, double tolerance, std::vector<Eigen::Index>& pivot_col,
                  std::vector<Eigen::Index>& free_col) {
  const Eigen::Index m = T.rows();
  const Eigen::Index n = T.cols();
  pivot_col.clear();
  free_col.clear();
  Eigen::Index rank = 0;
  for (Eigen::Index col = 0; col < n; ++col) {
    if (rank == m) {
      free_col.push_back(col);
      continue;
    }
    Eigen::Index best = rank;
    double best_abs = std::abs(T(rank, col));
    for (Eigen::Index r = rank + 1; r < m; ++r) {
      const double v = std::abs(T(r, col));
      if (v > best_abs) {
        best_abs = v;
        best = r;
      }
    }
    if (!(best_abs > tolerance)) {
      free_col.push_back(col);
      continue;
    }
    if (best != rank) T.row(best).swap(T.row(rank));
    double* pivot_row = T.row(rank).data();
    const double inverse = 1.0 / pivot_row[col];
    for (Eigen::Index c = col + 1; c < n; ++c) pivot_row[c] *= inverse;
    for (Eigen::Index f : free_col) pivot_row[f] *= inverse;
    pivot_row[col] = 1.0;
    for (Eigen::Index r = 0; r < m; ++r) {
      if (r == rank) continue;
      double* row = T.row(r).data();
      const double factor = row[col];
      if (factor == 0.0) continue;
      axpy_minus(row + col + 1, pivot_row + col + 1, factor, n - col - 1);
      for (Eigen::Index f : free_col) row[f] -= factor * pivot_row[f];
      row[col] = 0.0;
    }
    pivot_col.push_back(col);
    ++rank;
  }
}

}  // namespace

std::vector<char> eliminate(const Eigen::MatrixXd& points, Eigen::VectorXd& weights,
                            std::span<const long> sizes, long min_rows) {
  const Eigen::Index L = points.rows();
  const Eigen::Index n = points.cols();
  std::vector<char> alive(static_cast<std::size_t>(n), 1);
  if (n <= 1) return alive;
  const auto size_of = [&](Eigen::Index i) {
    return sizes.empty() ? 1L : sizes[static_cast<std::size_t>(i)];
  };

  // T = [points; 1] with every coordinate centred and scaled to unit range: row operations, so
  // the kernel is unchanged, but the factorization sees numbers of one magnitude.
  thread_local RowMatrix T;
  T.resize(L + 1, n);
  const double total = weights.sum();
  for (Eigen::Index l = 0; l < L; ++l) {
    double mean = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) mean += points(l, i) * weights[i];
    mean /= total;
    double scale = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double v = points(l, i) - mean;
      T(l, i) = v;
      scale = std::max(scale, std::abs(v));
    }
    if (scale > 0.0) T.row(l) *= 1.0 / scale;
  }
  T.row(L).setOnes();

  // Reduced row echelon form: basic columns (one per pivot row) and free columns. Free column f
  // gives the null vector v = e_f - sum_r T(r, f) e_{basic(r)} of the points' [p; 1].
  thread_local std::vector<Eigen::Index> pivot_col, free_col;
  gauss_jordan(T, 1e-11, pivot_col, free_col);
  const auto rank = static_cast<Eigen::Index>(pivot_col.size());
  const auto m = static_cast<Eigen::Index>(free_col.size());
  if (m == 0) return alive;

  // The free columns as one contiguous tableau F (rank x m): column k stays valid for the
  // current basis as points leave and free points enter it.
  thread_local RowMatrix F;
  F.resize(rank, m);
  for (Eigen::Index r = 0; r < rank; ++r) {
    for (Eigen::Index k = 0; k < m; ++k) F(r, k) = T(r, free_col[static_cast<std::size_t>(k)]);
  }
  thread_local std::vector<Eigen::Index> basic;
  basic.assign(pivot_col.begin(), pivot_col.end());

  long rows = 0;
  for (Eigen::Index i = 0; i < n; ++i) rows += size_of(i);
  for (Eigen::Index k = 0; k < m; ++k) {
    const Eigen::Index f = free_col[static_cast<std::size_t>(k)];
    // Ratio test along v (v_f = 1, v_basic(r) = -F(r, k)): the first weight to reach zero.
    Eigen::Index j = f;
    Eigen::Index j_row = -1;
    double alpha = weights[f];
    for (Eigen::Index r = 0; r < rank; ++r) {
      const double v = -F(r, k);
      if (!(v > 0.0)) continue;
      const double w = weights[basic[static_cast<std::size_t>(r)]];
      if (w < alpha * v) {
        alpha = w / v;
        j = basic[static_cast<std::size_t>(r)];
        j_row = r;
      }
    }
    if (rows - size_of(j) < min_rows) break;
    weights[f] -= alpha;
    for (Eigen::Index r = 0; r < rank; ++r) {
      double& w = weights[basic[static_cast<std::size_t>(r)]];
      w = std::max(0.0, w + alpha * F(r, k));
    }
    if (!(weights[f] > 0.0)) weights[f] = 0.0;
    weights[j] = 0.0;
    alive[static_cast<std::size_t>(j)] = 0;
    rows -= size_of(j);
    if (j_row < 0 || k + 1 == m) continue;
    // Basis exchange: f replaces j in row j_row; pivot the remaining free columns.
    const Eigen::Index rest = m - k - 1;
    double* pivot_row = F.row(j_row).data() + k + 1;
    const double inverse = 1.0 / F(j_row, k);
    for (Eigen::Index q = 0; q < rest; ++q) pivot_row[q] *= inverse;
    for (Eigen::Index r = 0; r < rank; ++r) {
      if (r == j_row) continue;
      const double factor = F(r, k);
      if (factor != 0.0) axpy_minus(F.row(r).data() + k + 1, pivot_row, factor, rest);
    }
    basic[static_cast<std::size_t>(j_row)] = f;
  }
  // Points whose weight rounded to zero carry nothing: drop them (unless that would break the
  // row floor, in which case they keep their tiny non-negative weight).
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!alive[static_cast<std::size_t>(i)] || weights[i] > 0.0) continue;
    const long size_i = size_of(i);
    if (rows - size_i < min_rows) continue;
    alive[static_cast<std::size_t>(i)] = 0;
    rows -= size_i;
  }
  return alive;
}

}  // namespace carat::internal
