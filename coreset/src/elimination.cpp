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

typedef double v4d __attribute__((vector_size(32)));

/// The tableau of the free columns, column-major: column k holds the coefficients of free point k
/// on the current basis rows, padded with zeros to a multiple of four rows.
struct Tableau {
  std::vector<double> data;  ///< cols x stride
  Eigen::Index rows = 0;     ///< basis rows
  Eigen::Index stride = 0;   ///< rows rounded up to 4

  void resize(Eigen::Index r, Eigen::Index c) {
    rows = r;
    stride = (r + 3) / 4 * 4;
    data.assign(static_cast<std::size_t>(c * stride), 0.0);
  }
  double* col(Eigen::Index k) { return data.data() + k * stride; }
};

/// Ratio test along the null vector of free column `column` (coefficient -column[r] on basis
/// row r): the smallest bw[r] / -column[r] over rows with -column[r] > 0, if it is below alpha
/// (then alpha becomes it and its first row is returned), else -1. Branch-free over the rows:
/// the signs are data, and a mispredicted branch per row cost more than the divisions.
CARAT_MULTIVERSION
Eigen::Index ratio_test(const double* __restrict column, const double* __restrict bw,
                        Eigen::Index stride, double* __restrict ratio, double& alpha) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  const v4d infinity = {inf, inf, inf, inf};
  const v4d zero = {0.0, 0.0, 0.0, 0.0};
  v4d best = infinity;
  for (Eigen::Index r = 0; r < stride; r += 4) {
    v4d c;
    v4d w;
    __builtin_memcpy(&c, column + r, sizeof(c));
    __builtin_memcpy(&w, bw + r, sizeof(w));
    const v4d v = -c;
    const v4d q = w / v;  // only kept where v > 0
    const v4d x = v > zero ? q : infinity;
    __builtin_memcpy(ratio + r, &x, sizeof(x));
    best = x < best ? x : best;
  }
  const double smallest = std::min(std::min(best[0], best[1]), std::min(best[2], best[3]));
  if (!(smallest < alpha)) return -1;
  alpha = smallest;
  Eigen::Index r = 0;
  while (ratio[r] != smallest) ++r;
  return r;
}

/// bw[r] = max(0, bw[r] + alpha * column[r]): the basis weights after a step of alpha.
CARAT_MULTIVERSION
void step_basis(double* __restrict bw, const double* __restrict column, double alpha,
                Eigen::Index stride) {
  const v4d zero = {0.0, 0.0, 0.0, 0.0};
  for (Eigen::Index r = 0; r < stride; r += 4) {
    v4d c;
    v4d w;
    __builtin_memcpy(&c, column + r, sizeof(c));
    __builtin_memcpy(&w, bw + r, sizeof(w));
    const v4d x = w + alpha * c;
    const v4d clamped = zero < x ? x : zero;
    __builtin_memcpy(bw + r, &clamped, sizeof(clamped));
  }
}

/// The basis exchange when free column k enters at basis row j_row: every later column c gets
/// F(j_row, c) / F(j_row, k) in row j_row and F(r, c) - F(r, k) * that in every other row.
CARAT_MULTIVERSION
void exchange(Tableau& F, Eigen::Index cols, Eigen::Index j_row, Eigen::Index k) {
  const Eigen::Index stride = F.stride;
  const double* __restrict entering = F.col(k);
  const double inverse = 1.0 / entering[j_row];
  for (Eigen::Index c = k + 1; c < cols; ++c) {
    double* __restrict column = F.col(c);
    const double pivot = column[j_row] * inverse;
    if (pivot == 0.0) continue;
    for (Eigen::Index r = 0; r < stride; ++r) column[r] -= entering[r] * pivot;
    column[j_row] = pivot;
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

const std::vector<char>& eliminate(const double* points, Eigen::Index L, Eigen::Index n,
                                   Eigen::Index stride, double* weights,
                                   std::span<const long> sizes, long min_rows) {
  // Scratch reused across calls: fresh heap pages cost a page fault each, which in a loop of
  // compressions that allocates and frees its own buffers was a third of the time.
  thread_local std::vector<char> alive;
  alive.assign(static_cast<std::size_t>(n), 1);
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

  // The free columns as a column-major tableau F (rank x m): column k stays valid for the
  // current basis as points leave and free points enter it.
  thread_local Tableau F;
  F.resize(rank, m);
  for (Eigen::Index k = 0; k < m; ++k) {
    double* column = F.col(k);
    const Eigen::Index f = free_col[static_cast<std::size_t>(k)];
    for (Eigen::Index r = 0; r < rank; ++r) column[r] = T(r, f);
  }
  thread_local std::vector<Eigen::Index> basic;
  basic.assign(pivot_col.begin(), pivot_col.end());
  // The basis points' weights by basis row (padding rows stay 0), written back at the end.
  thread_local std::vector<double> bw, ratio;
  bw.assign(static_cast<std::size_t>(F.stride), 0.0);
  ratio.resize(static_cast<std::size_t>(F.stride));
  for (Eigen::Index r = 0; r < rank; ++r)
    bw[static_cast<std::size_t>(r)] = weights[basic[static_cast<std::size_t>(r)]];

  long rows = 0;
  for (Eigen::Index i = 0; i < n; ++i) rows += size_of(i);
  for (Eigen::Index k = 0; k < m; ++k) {
    const Eigen::Index f = free_col[static_cast<std::size_t>(k)];
    // Ratio test along v (v_f = 1, v_basic(r) = -F(r, k)): the first weight to reach zero.
    double alpha = weights[f];
    const Eigen::Index j_row = ratio_test(F.col(k), bw.data(), F.stride, ratio.data(), alpha);
    const Eigen::Index j = j_row < 0 ? f : basic[static_cast<std::size_t>(j_row)];
    if (rows - size_of(j) < min_rows) break;
    weights[f] -= alpha;
    step_basis(bw.data(), F.col(k), alpha, F.stride);
    if (!(weights[f] > 0.0)) weights[f] = 0.0;
    weights[j] = 0.0;
    alive[static_cast<std::size_t>(j)] = 0;
    rows -= size_of(j);
    if (j_row < 0) continue;
    // Basis exchange: f replaces j in row j_row.
    bw[static_cast<std::size_t>(j_row)] = weights[f];
    basic[static_cast<std::size_t>(j_row)] = f;
    if (k + 1 < m) exchange(F, m, j_row, k);
  }
  for (Eigen::Index r = 0; r < rank; ++r)
    weights[basic[static_cast<std::size_t>(r)]] = bw[static_cast<std::size_t>(r)];
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
