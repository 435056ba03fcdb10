#include "elimination.hpp"
#include "simd.hpp"

#include <cmath>
#include <limits>


namespace carat::internal {
namespace {

/// y -= a * x over n contiguous doubles (vectorizes: no reduction).
CARAT_MULTIVERSION
void axpy_minus(double* y, const double* x, double a, Eigen::Index n) {
  for (Eigen::Index i = 0; i < n; ++i) y[i] -= a * x[i];
}

}  // namespace

std::vector<char> eliminate(const Eigen::MatrixXd& points, Eigen::VectorXd& weights,
                            std::span<const long> sizes, long min_rows) {
  const Eigen::Index L = points.rows();
  const Eigen::Index n = points.cols();
  std::vector<char> alive(static_cast<std::size_t>(n), 1);
  if (n <= 1) return alive;
  // [points; 1] with every coordinate centred and scaled to unit range: row operations, so the
  // kernel is unchanged, but the factorization sees numbers of one magnitude.
  Eigen::MatrixXd A(L + 1, n);
  const double total = weights.sum();
  for (Eigen::Index l = 0; l < L; ++l) {
    const double mean = points.row(l).dot(weights) / total;
    A.row(l) = points.row(l).array() - mean;
    const double scale = A.row(l).cwiseAbs().maxCoeff();
    if (scale > 0.0) A.row(l) /= scale;
  }
  A.row(L).setOnes();
  // Null space of A by Gauss-Jordan elimination with partial pivoting (rows of A are O(1) after
  // the scaling above): pivot columns get a unit pivot row, free columns give one null vector
  // each, v = e_f - sum_r R(r, f) e_{pivot(r)}.
  const Eigen::Index rows_A = L + 1;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> R = A;
  std::vector<Eigen::Index> pivot_col;
  std::vector<Eigen::Index> free_col;
  const double tolerance = 1e-11;
  Eigen::Index rank = 0;
  for (Eigen::Index col = 0; col < n; ++col) {
    if (rank == rows_A) {
      free_col.push_back(col);
      continue;
    }
    Eigen::Index best = rank;
    double best_abs = std::abs(R(rank, col));
    for (Eigen::Index r = rank + 1; r < rows_A; ++r) {
      const double v = std::abs(R(r, col));
      if (v > best_abs) {
        best_abs = v;
        best = r;
      }
    }
    if (!(best_abs > tolerance)) {
      free_col.push_back(col);
      continue;
    }
    if (best != rank) R.row(best).swap(R.row(rank));
    R.row(rank) /= R(rank, col);
    for (Eigen::Index r = 0; r < rows_A; ++r) {
      if (r == rank) continue;
      const double factor = R(r, col);
      if (factor != 0.0) axpy_minus(R.row(r).data(), R.row(rank).data(), factor, n);
    }
    pivot_col.push_back(col);
    ++rank;
  }
  if (free_col.empty()) return alive;
  Eigen::MatrixXd N = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(free_col.size()));
  for (std::size_t f = 0; f < free_col.size(); ++f) {
    const auto k = static_cast<Eigen::Index>(f);
    N(free_col[f], k) = 1.0;
    for (Eigen::Index r = 0; r < rank; ++r) N(pivot_col[static_cast<std::size_t>(r)], k) = -R(r, free_col[f]);
  }
  long rows = 0;
  for (Eigen::Index i = 0; i < n; ++i) rows += sizes.empty() ? 1 : sizes[static_cast<std::size_t>(i)];
  const Eigen::Index m = N.cols();
  for (Eigen::Index k = 0; k < m; ++k) {
    auto v = N.col(k);
    const double vmax = v.cwiseAbs().maxCoeff();
    if (!(vmax > 1e-13)) continue;  // numerically zero on the survivors
    // Ratio test over positive entries (a null vector sums to zero, so it has some).
    Eigen::Index j = -1;
    double alpha = std::numeric_limits<double>::infinity();
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!alive[static_cast<std::size_t>(i)] || !(v[i] > 0.0)) continue;
      const double ratio = weights[i] / v[i];
      if (ratio < alpha) {
        alpha = ratio;
        j = i;
      }
    }
    if (j < 0) continue;
    const long size_j = sizes.empty() ? 1 : sizes[static_cast<std::size_t>(j)];
    if (rows - size_j < min_rows) break;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (!alive[static_cast<std::size_t>(i)]) continue;
      const double updated = weights[i] - alpha * v[i];
      weights[i] = updated > 0.0 ? updated : 0.0;
    }
    weights[j] = 0.0;
    alive[static_cast<std::size_t>(j)] = 0;
    rows -= size_j;
    // Zero entry j in the remaining null vectors so that they stay null vectors of the survivors.
    const double vj = v[j];
    for (Eigen::Index q = k + 1; q < m; ++q) {
      const double factor = N(j, q) / vj;
      if (factor != 0.0) axpy_minus(N.col(q).data(), v.data(), factor, n);
    }
  }
  // Points whose weight rounded to zero carry nothing: drop them (unless that would break the
  // row floor, in which case they keep their tiny non-negative weight).
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!alive[static_cast<std::size_t>(i)] || weights[i] > 0.0) continue;
    const long size_i = sizes.empty() ? 1 : sizes[static_cast<std::size_t>(i)];
    if (rows - size_i < min_rows) continue;
    alive[static_cast<std::size_t>(i)] = 0;
    rows -= size_i;
  }
  return alive;
}

}  // namespace carat::internal
