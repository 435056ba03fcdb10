#include "elimination.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "simd.hpp"

namespace carat::internal {
namespace {

/// Row-major matrix with rows padded to a multiple of 8 doubles (zeros beyond the columns), so
/// that row updates run whole vectors from an aligned column on.
struct PaddedMatrix {
  std::vector<double> data;  ///< rows x stride, row-major
  Eigen::Index rows = 0;     ///< number of rows
  Eigen::Index cols = 0;     ///< number of live columns
  Eigen::Index stride = 0;   ///< doubles per row (cols rounded up to 8)

  void resize(Eigen::Index r, Eigen::Index c) {
    rows = r;
    cols = c;
    stride = (c + 7) / 8 * 8;
    data.assign(static_cast<std::size_t>(r * stride), 0.0);
  }
  double* row(Eigen::Index r) { return data.data() + r * stride; }
  double& operator()(Eigen::Index r, Eigen::Index c) {
    return data[static_cast<std::size_t>(r * stride + c)];
  }
};

/// Gauss-Jordan with partial pivoting on T (in place): column by column, a pivot above
/// `tolerance` becomes a unit pivot row and is cleared from every other row; a column without one
/// is free. Returns the rank; pivot_col[r] is the basic column of row r.
CARAT_MULTIVERSION
Eigen::Index gauss_jordan(PaddedMatrix& T, double tolerance, std::vector<Eigen::Index>& pivot_col,
                          std::vector<Eigen::Index>& free_col) {
  const Eigen::Index m = T.rows;
  const Eigen::Index n = T.cols;
  const Eigen::Index stride = T.stride;
  double* __restrict base = T.data.data();
  pivot_col.clear();
  free_col.clear();
  Eigen::Index rank = 0;
  for (Eigen::Index col = 0; col < n; ++col) {
    if (rank == m) {
      free_col.push_back(col);
      continue;
    }
    Eigen::Index best = rank;
    double best_abs = std::abs(base[rank * stride + col]);
    for (Eigen::Index r = rank + 1; r < m; ++r) {
      const double v = std::abs(base[r * stride + col]);
      if (v > best_abs) {
        best_abs = v;
        best = r;
      }
    }
    if (!(best_abs > tolerance)) {
      free_col.push_back(col);
      continue;
    }
    // Columns before `from` are zero in the pivot row (basic columns) or not read again.
    const Eigen::Index first = free_col.empty() ? col : std::min(col, free_col.front());
    const Eigen::Index from = first / 8 * 8;
    double* __restrict pivot_row = base + rank * stride;
    if (best != rank) {
      double* __restrict other = base + best * stride;
      for (Eigen::Index c = from; c < stride; ++c) std::swap(pivot_row[c], other[c]);
    }
    const double inverse = 1.0 / pivot_row[col];
    for (Eigen::Index c = from; c < stride; ++c) pivot_row[c] *= inverse;
    pivot_row[col] = 1.0;
    for (Eigen::Index r = 0; r < m; ++r) {
      if (r == rank) continue;
      double* __restrict row = base + r * stride;
      const double factor = row[col];
      if (factor == 0.0) continue;
      for (Eigen::Index c = from; c < stride; ++c) row[c] -= factor * pivot_row[c];
      row[col] = 0.0;
    }
    pivot_col.push_back(col);
    ++rank;
  }
  return rank;
}

/// The basis exchange of the tableau F when free column k enters at row j_row: pivot row
/// divided by F(j_row, k), the column cleared from every other row (columns after k only).
CARAT_MULTIVERSION
void exchange(PaddedMatrix& F, Eigen::Index rank, Eigen::Index j_row, Eigen::Index k) {
  const Eigen::Index stride = F.stride;
  const Eigen::Index from = (k + 1) / 8 * 8;
  double* __restrict base = F.data.data();
  double* __restrict pivot_row = base + j_row * stride;
  const double inverse = 1.0 / pivot_row[k];
  for (Eigen::Index c = from; c < stride; ++c) pivot_row[c] *= inverse;
  for (Eigen::Index r = 0; r < rank; ++r) {
    if (r == j_row) continue;
    double* __restrict row = base + r * stride;
    const double factor = row[k];
    if (factor == 0.0) continue;
    for (Eigen::Index c = from; c < stride; ++c) row[c] -= factor * pivot_row[c];
  }
}

/// t = (p - weighted mean of p) / max |p - mean| over n points (t = 0 when p is constant).
/// Four partial sums and maxima (fixed order), so that the reductions vectorize.
CARAT_MULTIVERSION
void centre_and_scale(const double* __restrict p, const double* __restrict w, Eigen::Index n,
                      double total, double* __restrict t) {
  typedef double v4d __attribute__((vector_size(32)));
  v4d acc = {0.0, 0.0, 0.0, 0.0};
  Eigen::Index i = 0;
  for (; i + 3 < n; i += 4) {
    v4d pv;
    v4d wv;
    __builtin_memcpy(&pv, p + i, sizeof(pv));
    __builtin_memcpy(&wv, w + i, sizeof(wv));
    acc += pv * wv;
  }
  double mean = (acc[0] + acc[1]) + (acc[2] + acc[3]);
  for (; i < n; ++i) mean += p[i] * w[i];
  mean /= total;
  for (i = 0; i < n; ++i) t[i] = p[i] - mean;
  double m[4] = {0.0, 0.0, 0.0, 0.0};
  for (i = 0; i + 3 < n; i += 4) {
    for (int q = 0; q < 4; ++q) m[q] = std::max(m[q], std::abs(t[i + q]));
  }
  for (; i < n; ++i) m[0] = std::max(m[0], std::abs(t[i]));
  const double scale = std::max(std::max(m[0], m[1]), std::max(m[2], m[3]));
  if (!(scale > 0.0)) return;
  const double inverse = 1.0 / scale;
  for (i = 0; i < n; ++i) t[i] *= inverse;
}

}  // namespace

std::vector<char> eliminate(const double* points, Eigen::Index L, Eigen::Index n,
                            Eigen::Index stride, double* weights, std::span<const long> sizes,
                            long min_rows) {
  std::vector<char> alive(static_cast<std::size_t>(n), 1);
  if (n <= 1) return alive;
  const auto size_of = [&](Eigen::Index i) {
    return sizes.empty() ? 1L : sizes[static_cast<std::size_t>(i)];
  };

  // T = [points; 1] with every coordinate centred and scaled to unit range: row operations, so
  // the kernel is unchanged, but the factorization sees numbers of one magnitude.
  thread_local PaddedMatrix T;
  T.resize(L + 1, n);
  double total = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) total += weights[i];
  for (Eigen::Index l = 0; l < L; ++l) {
    const double* p = points + l * stride;
    double* t = T.row(l);
    centre_and_scale(p, weights, n, total, t);
  }
  double* ones = T.row(L);
  for (Eigen::Index i = 0; i < n; ++i) ones[i] = 1.0;

  // Reduced row echelon form: basic columns (one per pivot row) and free columns. Free column f
  // gives the null vector v = e_f - sum_r T(r, f) e_{basic(r)} of the points' [p; 1].
  thread_local std::vector<Eigen::Index> pivot_col, free_col;
  const Eigen::Index rank = gauss_jordan(T, 1e-11, pivot_col, free_col);
  const auto m = static_cast<Eigen::Index>(free_col.size());
  if (m == 0) return alive;

  // The free columns as one contiguous tableau F (rank x m): column k stays valid for the
  // current basis as points leave and free points enter it.
  thread_local PaddedMatrix F;
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
    // Basis exchange: f replaces j in row j_row.
    exchange(F, rank, j_row, k);
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
