#include "elimination.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "carat/base/interruption.hpp"
#include "simd.hpp"

namespace carat::internal {
namespace {

/// Row-major matrix with rows padded to a multiple of 8 doubles (zeros beyond the columns), so
/// that row updates run whole vectors from an aligned column on.
struct PaddedMatrix {
  AlignedDoubles data;      ///< rows x stride, row-major
  Eigen::Index rows = 0;    ///< number of rows
  Eigen::Index cols = 0;    ///< number of live columns
  Eigen::Index stride = 0;  ///< doubles per row (cols rounded up to 8)

  /// Shape r x c; contents unspecified except the padding columns, which are zero.
  void resize(Eigen::Index r, Eigen::Index c) {
    rows = r;
    cols = c;
    stride = (c + 7) / 8 * 8;
    data.resize(static_cast<std::size_t>(r * stride));
    for (Eigen::Index i = 0; i < r; ++i) std::fill(row(i) + c, row(i) + stride, 0.0);
  }
  double* row(Eigen::Index r) { return data.data() + r * stride; }
  double& operator()(Eigen::Index r, Eigen::Index c) {
    return data[static_cast<std::size_t>(r * stride + c)];
  }
};

/// Pivots per panel of the blocked Gauss-Jordan.
constexpr int kPanel = 8;

/// The delayed update of one panel on columns [begin, end) (multiples of 8), the same
/// arithmetic as eliminating the panel's pivots one by one over these columns: pivot k (row
/// p0 + k, 1 / pivot in scale[k]) is used after the pivots before it, w_k = scale[k] (T[p0 + k]
/// - sum_{j<k} F[p0 + k, j] w_j); then every row r outside the pivot rows gets
/// T[r] - sum_k F[r, k] w_k and pivot row k gets w_k - sum_{j>k} F[p0 + k, j] w_j. F holds each
/// row's elimination factors (m x kPanel, zero beyond count). One pass over the columns, a
/// vector V of them at a time, with the pivots' w in registers: kPanel multiply-adds per load
/// and store instead of one.
template <class V, int N>
__attribute__((always_inline)) inline void apply_panel_body(double* const* __restrict row_of,
                                                            Eigen::Index rows, Eigen::Index p0,
                                                            int count, const double* __restrict F,
                                                            const double* __restrict scale,
                                                            Eigen::Index begin, Eigen::Index end) {
  constexpr int W = sizeof(V) / sizeof(double);
  Eigen::Index c = begin;
  // N vectors of columns per pass (each factor load serves N multiply-adds), then one. Inlined
  // always: a lambda does not inherit the target of the function around it.
  const auto pass = [&]<int M>(std::integral_constant<int, M>) __attribute__((always_inline)) {
    V w[M][kPanel];
    for (int q = 0; q < M; ++q) {
      for (int k = 0; k < kPanel; ++k) {
        if (k < count) {
          V a;
          __builtin_memcpy(&a, row_of[p0 + k] + c + q * W, sizeof(V));
          const double* f = F + (p0 + k) * kPanel;
          for (int j = 0; j < k; ++j) a -= f[j] * w[q][j];
          w[q][k] = scale[k] * a;
        } else {
          w[q][k] = V{} * 0.0;
        }
      }
    }
    for (Eigen::Index r = 0; r < rows; ++r) {
      if (r == p0) {
        r = p0 + count - 1;
        continue;
      }
      double* __restrict row = row_of[r] + c;
      const double* f = F + r * kPanel;
      V v[M];
      for (int q = 0; q < M; ++q) __builtin_memcpy(&v[q], row + q * W, sizeof(V));
      for (int k = 0; k < kPanel; ++k) {
        for (int q = 0; q < M; ++q) v[q] -= f[k] * w[q][k];
      }
      for (int q = 0; q < M; ++q) __builtin_memcpy(row + q * W, &v[q], sizeof(V));
    }
    for (int q = 0; q < M; ++q) {
      for (int k = 0; k < count; ++k) {
        V t = w[q][k];
        const double* f = F + (p0 + k) * kPanel;
        for (int j = k + 1; j < count; ++j) t -= f[j] * w[q][j];
        __builtin_memcpy(row_of[p0 + k] + c + q * W, &t, sizeof(V));
      }
    }
  };
  for (; c + N * W <= end; c += N * W) pass(std::integral_constant<int, N>{});
  for (; c < end; c += W) pass(std::integral_constant<int, 1>{});
}

/// apply_panel_body four columns at a time (eight pivots' vectors fit 16 registers).
CARAT_MULTIVERSION
void apply_panel_4(double* const* row_of, Eigen::Index rows, Eigen::Index p0, int count,
                   const double* F, const double* scale, Eigen::Index begin, Eigen::Index end) {
  apply_panel_body<v4d, 1>(row_of, rows, p0, count, F, scale, begin, end);
}

#if CARAT_HAVE_AVX512_PATH
/// apply_panel_body sixteen columns at a time (AVX-512: 32 registers hold two columns of eight).
CARAT_TARGET_AVX512
void apply_panel_8(double* const* row_of, Eigen::Index rows, Eigen::Index p0, int count,
                   const double* F, const double* scale, Eigen::Index begin, Eigen::Index end) {
  apply_panel_body<v8d, 2>(row_of, rows, p0, count, F, scale, begin, end);
}
#endif

/// apply_panel_body at the vector width this CPU has.
void apply_panel(double* const* row_of, Eigen::Index rows, Eigen::Index p0, int count,
                 const double* F, const double* scale, Eigen::Index begin, Eigen::Index end) {
#if CARAT_HAVE_AVX512_PATH
  if (cpu_has_avx512()) {
    apply_panel_8(row_of, rows, p0, count, F, scale, begin, end);
    return;
  }
#endif
  apply_panel_4(row_of, rows, p0, count, F, scale, begin, end);
}

/// out = lanes (I0, ..., I7) of the sixteen lanes of a then b (GCC's and Clang's shuffle
/// builtins differ in spelling).
template <int I0, int I1, int I2, int I3, int I4, int I5, int I6, int I7>
__attribute__((always_inline)) inline void shuffle8(const v8d& a, const v8d& b, v8d& out) {
#if defined(__clang__)
  out = __builtin_shufflevector(a, b, I0, I1, I2, I3, I4, I5, I6, I7);
#else
  const v8l lanes = {I0, I1, I2, I3, I4, I5, I6, I7};
  out = __builtin_shuffle(a, b, lanes);
#endif
}

/// Transposes the 8 x 8 block held by rows x[0..8) in registers: on return x[j] holds what was
/// column j.
__attribute__((always_inline)) inline void transpose8(v8d (&x)[8]) {
  v8d t[8];
  for (int i = 0; i < 8; i += 2) {
    shuffle8<0, 8, 2, 10, 4, 12, 6, 14>(x[i], x[i + 1], t[i]);
    shuffle8<1, 9, 3, 11, 5, 13, 7, 15>(x[i], x[i + 1], t[i + 1]);
  }
  // u[0..4) from rows 0-3: columns {0,4}, {2,6}, {1,5}, {3,7}; u[4..8) the same from rows 4-7.
  v8d u[8];
  for (int h = 0; h < 8; h += 4) {
    shuffle8<0, 1, 8, 9, 4, 5, 12, 13>(t[h], t[h + 2], u[h]);
    shuffle8<2, 3, 10, 11, 6, 7, 14, 15>(t[h], t[h + 2], u[h + 1]);
    shuffle8<0, 1, 8, 9, 4, 5, 12, 13>(t[h + 1], t[h + 3], u[h + 2]);
    shuffle8<2, 3, 10, 11, 6, 7, 14, 15>(t[h + 1], t[h + 3], u[h + 3]);
  }
  const int first[4] = {0, 2, 1, 3};  // the column u[i] starts with
  for (int i = 0; i < 4; ++i) {
    shuffle8<0, 1, 2, 3, 8, 9, 10, 11>(u[i], u[i + 4], x[first[i]]);
    shuffle8<4, 5, 6, 7, 12, 13, 14, 15>(u[i], u[i + 4], x[first[i] + 4]);
  }
}

/// Gauss-Jordan with partial pivoting on T (in place), blocked: panels of kPanel columns are
/// eliminated column by column on their own columns only (a pivot above `tolerance` becomes a
/// unit pivot row and is cleared from every other row; a column without one is free), in a
/// column-major copy of the panel, recording each row's factors, and the rest of the matrix then
/// gets the panel's row operations in one pass (apply_panel). Returns the rank; pivot_col[r] is
/// the basic column of row r, which lies at row_of[r] (rows trade places by pointer, not by
/// copying them). On return the free columns hold the reduced row echelon form; the basic
/// columns (unit vectors there) are left unspecified, as nothing reads them.
CARAT_MULTIVERSION_WIDE
Eigen::Index gauss_jordan(PaddedMatrix& T, double tolerance, std::vector<Eigen::Index>& pivot_col,
                          std::vector<Eigen::Index>& free_col, std::vector<double*>& row_of) {
  const Eigen::Index m = T.rows;
  const Eigen::Index n = T.cols;
  const Eigen::Index stride = T.stride;
  pivot_col.clear();
  free_col.clear();
  // Rows are exchanged by their pointers only: row_of[r] is where row r of the elimination lies.
  row_of.resize(static_cast<std::size_t>(m));
  for (Eigen::Index r = 0; r < m; ++r) row_of[static_cast<std::size_t>(r)] = T.row(r);
  // Each row's elimination factor per pivot of the current panel (m x kPanel), and the panel
  // itself column-major (kPanel columns of mp rows, rows past m zero).
  const Eigen::Index mp = (m + 7) / 8 * 8;
  thread_local AlignedDoubles F, panel_columns, factor;
  F.resize(static_cast<std::size_t>(m * kPanel));
  panel_columns.assign(static_cast<std::size_t>(kPanel * mp), 0.0);
  factor.resize(static_cast<std::size_t>(mp));
  double* __restrict pc = panel_columns.data();
  double scale[kPanel];
  Eigen::Index rank = 0;
  for (Eigen::Index panel = 0; panel < n; panel += kPanel) {
    interruption_point();  // a panel of a large tableau takes milliseconds
    if (rank == m) {
      for (Eigen::Index c = panel; c < n; ++c) free_col.push_back(c);
      break;
    }
    // The panel, column-major: 8 x 8 blocks transposed in registers (rows past m zero).
    for (Eigen::Index r0 = 0; r0 < m; r0 += 8) {
      v8d x[8];
      for (int i = 0; i < 8; ++i) {
        x[i] = v8d{} * 0.0;
        if (r0 + i < m)
          __builtin_memcpy(&x[i], row_of[static_cast<std::size_t>(r0 + i)] + panel, sizeof(v8d));
      }
      transpose8(x);
      for (int j = 0; j < kPanel; ++j) __builtin_memcpy(pc + j * mp + r0, &x[j], sizeof(v8d));
    }
    const Eigen::Index p0 = rank;
    int count = 0;
    const Eigen::Index panel_end = std::min<Eigen::Index>(n, panel + kPanel);
    for (Eigen::Index col = panel; col < panel_end; ++col) {
      if (rank == m) {
        free_col.push_back(col);
        continue;
      }
      double* __restrict column = pc + (col - panel) * mp;
      // The largest |entry| in rows [rank, m) and the first row that holds it, in one pass:
      // eight independent maxima with the first row of each (rows before rank masked out, rows
      // past m are zero), then the largest of the eight, the lowest row among equals.
      const v8d none = {-1.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0};
      const v8d lane = {0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0};
      v8d largest = none;
      v8d where = lane;
      for (Eigen::Index r = rank / 8 * 8; r < mp; r += 8) {
        v8d v;
        __builtin_memcpy(&v, column + r, sizeof(v));
        v = v < 0.0 ? -v : v;
        const v8d row = lane + static_cast<double>(r);
        v = row < static_cast<double>(rank) ? none : v;
        const v8l larger = v > largest;
        largest = larger ? v : largest;
        where = larger ? row : where;
      }
      double best_abs = largest[0];
      double best_row = where[0];
      for (int q = 1; q < 8; ++q) {
        if (largest[q] > best_abs || (largest[q] == best_abs && where[q] < best_row)) {
          best_abs = largest[q];
          best_row = where[q];
        }
      }
      const auto best = static_cast<Eigen::Index>(best_row);
      if (!(best_abs > tolerance)) {
        free_col.push_back(col);
        continue;
      }
      if (best != rank) {
        // Whole rows trade places (their columns outside the panel are brought up to date
        // later), and so do their panel entries and factors of this panel.
        std::swap(row_of[static_cast<std::size_t>(rank)], row_of[static_cast<std::size_t>(best)]);
        for (int j = 0; j < kPanel; ++j) {
          std::swap(F[rank * kPanel + j], F[best * kPanel + j]);
          std::swap(pc[j * mp + rank], pc[j * mp + best]);
        }
      }
      const double inverse = 1.0 / column[rank];
      scale[count] = inverse;
      double pivot[kPanel];
      for (int j = 0; j < kPanel; ++j) pivot[j] = pc[j * mp + rank] * inverse;
      pivot[col - panel] = 1.0;
      // The factors are the pivot column's entries; the pivot row's own is unused.
      for (Eigen::Index r = 0; r < m; ++r) F[r * kPanel + count] = column[r];
      F[rank * kPanel + count] = 0.0;
      // Every panel column minus factor x pivot entry (the pivot column becomes exactly zero
      // off the pivot: f - f * 1), then the pivot row set to the normalized one.
      std::copy(column, column + mp, factor.begin());
      for (int j = 0; j < kPanel; ++j) {
        double* __restrict target = pc + j * mp;
        const double pj = pivot[j];
        if (pj == 0.0) continue;  // e.g. the panel's basic columns so far: nothing changes
        for (Eigen::Index r = 0; r < mp; ++r) target[r] -= factor[static_cast<std::size_t>(r)] * pj;
        target[rank] = pj;
      }
      pivot_col.push_back(col);
      ++count;
      ++rank;
    }
    // Back to T: only the panel's free columns are read again (row operations act on every
    // column alone, so basic columns left stale in T change nothing else).
    for (auto f = free_col.rbegin(); f != free_col.rend() && *f >= panel; ++f) {
      const double* column = pc + (*f - panel) * mp;
      for (Eigen::Index r = 0; r < m; ++r) row_of[static_cast<std::size_t>(r)][*f] = column[r];
    }
    if (count == 0) continue;
    // Every pivot wrote its factor for every row; pivots the panel did not get have none (the
    // kernels below run all kPanel with zero coefficients there, which must not meet stale
    // values).
    if (count < kPanel) {
      for (Eigen::Index r = 0; r < m; ++r) {
        std::fill(F.begin() + r * kPanel + count, F.begin() + (r + 1) * kPanel, 0.0);
      }
    }
    // Columns the panel's operations change outside the panel: free columns before it (their
    // 8-column blocks; the basic columns there are not read again) and every column after it.
    const Eigen::Index first_free = free_col.empty() ? panel : std::min(panel, free_col.front());
    apply_panel(row_of.data(), m, p0, count, F.data(), scale, first_free / 8 * 8, panel);
    apply_panel(row_of.data(), m, p0, count, F.data(), scale, panel + kPanel, stride);
  }
  return rank;
}

/// The tableau of the free columns, column-major: column k holds the coefficients of free point k
/// on the current basis rows, padded with zeros to a multiple of eight rows.
struct Tableau {
  AlignedDoubles data;      ///< cols x stride
  Eigen::Index rows = 0;    ///< basis rows
  Eigen::Index stride = 0;  ///< rows rounded up to 8

  /// Shape r x c; rows [0, r) unspecified (the caller writes them), the padding rows zero.
  void resize(Eigen::Index r, Eigen::Index c) {
    rows = r;
    stride = (r + 7) / 8 * 8;
    data.resize(static_cast<std::size_t>(c * stride));
    for (Eigen::Index k = 0; k < c; ++k) std::fill(col(k) + r, col(k) + stride, 0.0);
  }
  double* col(Eigen::Index k) { return data.data() + k * stride; }
};

/// F = the free columns of the rows row_of[0, rank) (the rows of T in elimination order): 8 x 8
/// blocks transposed in registers where 8 free columns are consecutive in T, one entry at a time
/// elsewhere. F's rows past rank stay zero.
CARAT_MULTIVERSION_WIDE
void copy_tableau(double* const* row_of, Eigen::Index rank,
                  const std::vector<Eigen::Index>& free_col, Tableau& F) {
  const auto m = static_cast<Eigen::Index>(free_col.size());
  const Eigen::Index* f = free_col.data();
  for (Eigen::Index r0 = 0; r0 < rank; r0 += 8) {
    const int rows = static_cast<int>(std::min<Eigen::Index>(8, rank - r0));
    Eigen::Index k = 0;
    for (; k + 8 <= m; k += 8) {
      if (f[k + 7] != f[k] + 7) {
        for (int j = 0; j < 8; ++j) {
          for (int i = 0; i < rows; ++i) F.col(k + j)[r0 + i] = row_of[r0 + i][f[k + j]];
        }
        continue;
      }
      v8d x[8];
      for (int i = 0; i < 8; ++i) {
        x[i] = v8d{} * 0.0;
        if (i < rows) __builtin_memcpy(&x[i], row_of[r0 + i] + f[k], sizeof(v8d));
      }
      transpose8(x);
      for (int j = 0; j < 8; ++j) __builtin_memcpy(F.col(k + j) + r0, &x[j], sizeof(v8d));
    }
    for (; k < m; ++k) {
      for (int i = 0; i < rows; ++i) F.col(k)[r0 + i] = row_of[r0 + i][f[k]];
    }
  }
}

/// Ratio test along the null vector of free column `column` (coefficient -column[r] on basis
/// row r): the smallest bw[r] / -column[r] over rows with -column[r] > 0, if it is below alpha
/// (then alpha becomes it and its first row is returned), else -1. Branch-free over the rows:
/// the signs are data, and a mispredicted branch per row cost more than the divisions.
CARAT_MULTIVERSION_WIDE
Eigen::Index ratio_test_exact(const double* __restrict column, const double* __restrict bw,
                              Eigen::Index stride, double* __restrict ratio, double& alpha) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  const v8d infinity = v8d{} + inf;
  const v8d zero = v8d{} * 0.0;
  v8d best = infinity;
  for (Eigen::Index r = 0; r < stride; r += 8) {
    v8d c;
    v8d w;
    __builtin_memcpy(&c, column + r, sizeof(c));
    __builtin_memcpy(&w, bw + r, sizeof(w));
    const v8d v = -c;
    const v8d q = w / v;  // only kept where v > 0
    const v8d x = v > zero ? q : infinity;
    __builtin_memcpy(ratio + r, &x, sizeof(x));
    best = x < best ? x : best;
  }
  double smallest = best[0];
  for (int q = 1; q < 8; ++q) smallest = std::min(smallest, best[q]);
  if (!(smallest < alpha)) return -1;
  alpha = smallest;
  Eigen::Index r = 0;
  while (ratio[r] != smallest) ++r;
  return r;
}

#if CARAT_HAVE_AVX512_PATH
/// ratio_test with the same result, fewer divisions: approximate ratios w * (1 / v) (a 14-bit
/// reciprocal and one Newton step, relative error below 4e-9) find the rows whose ratio can be
/// the smallest (within 1e-7 of the smallest approximation), and only those are divided exactly.
/// A reciprocal that is 0 or not finite (v huge or denormal) sends the column to ratio_test_exact.
CARAT_TARGET_AVX512
Eigen::Index ratio_test_512(const double* __restrict column, const double* __restrict bw,
                            Eigen::Index stride, double* __restrict ratio, double& alpha) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  const v8d infinity = v8d{} + inf;
  const v8d zero = v8d{} * 0.0;
  v8d best = infinity;
  v8l bad = v8l{} * 0;
  for (Eigen::Index r = 0; r < stride; r += 8) {
    v8d c;
    v8d w;
    __builtin_memcpy(&c, column + r, sizeof(c));
    __builtin_memcpy(&w, bw + r, sizeof(w));
    const v8d v = -c;
    const v8d x0 = __builtin_ia32_rcp14pd512_mask(v, zero, static_cast<unsigned char>(0xFF));
    const v8d x = x0 * (2.0 - v * x0);
    const v8l positive = v > zero;
    bad |= positive & ~((x0 > zero) & (x0 < infinity));
    const v8d q = positive ? w * x : infinity;
    __builtin_memcpy(ratio + r, &q, sizeof(q));
    best = q < best ? q : best;
  }
  bool any_bad = false;
  for (int q = 0; q < 8; ++q) any_bad = any_bad || bad[q] != 0;
  if (any_bad) return ratio_test_exact(column, bw, stride, ratio, alpha);
  double approximate = best[0];
  for (int q = 1; q < 8; ++q) approximate = std::min(approximate, best[q]);
  constexpr double kMargin = 1e-7;
  if (!(approximate < alpha * (1.0 + kMargin) + std::numeric_limits<double>::min())) return -1;
  const double threshold = approximate * (1.0 + kMargin) + std::numeric_limits<double>::min();
  double smallest = std::numeric_limits<double>::infinity();
  Eigen::Index first = -1;
  for (Eigen::Index r = 0; r < stride; r += 8) {
    v8d q;
    __builtin_memcpy(&q, ratio + r, sizeof(q));
    const v8l candidate = q <= threshold;
    bool any = false;
    for (int lane = 0; lane < 8; ++lane) any = any || candidate[lane] != 0;
    if (!any) continue;
    for (int lane = 0; lane < 8; ++lane) {
      if (candidate[lane] == 0) continue;
      const double exact = bw[r + lane] / -column[r + lane];
      if (exact < smallest) {
        smallest = exact;
        first = r + lane;
      }
    }
  }
  if (!(smallest < alpha)) return -1;
  alpha = smallest;
  return first;
}
#endif

/// ratio_test_exact's result, with the fewest divisions this CPU allows.
Eigen::Index ratio_test(const double* column, const double* bw, Eigen::Index stride, double* ratio,
                        double& alpha) {
#if CARAT_HAVE_AVX512_PATH
  if (cpu_has_avx512()) return ratio_test_512(column, bw, stride, ratio, alpha);
#endif
  return ratio_test_exact(column, bw, stride, ratio, alpha);
}

/// bw[r] = max(0, bw[r] + alpha * column[r]): the basis weights after a step of alpha.
CARAT_MULTIVERSION_WIDE
void step_basis(double* __restrict bw, const double* __restrict column, double alpha,
                Eigen::Index stride) {
  const v8d zero = v8d{} * 0.0;
  for (Eigen::Index r = 0; r < stride; r += 8) {
    v8d c;
    v8d w;
    __builtin_memcpy(&c, column + r, sizeof(c));
    __builtin_memcpy(&w, bw + r, sizeof(w));
    const v8d x = w + alpha * c;
    const v8d clamped = zero < x ? x : zero;
    __builtin_memcpy(bw + r, &clamped, sizeof(clamped));
  }
}

/// Basis exchanges not yet applied to the tableau's later columns (at most kPanel). Exchange i
/// (free column entering at basis row row[i], 1 / its entry there in inverse[i]) maps a column c
/// to c - e_i p_i with p_i = c[row[i]] inverse[i], where e_i is the entering column with 1
/// subtracted at row[i] (so that c[row[i]] becomes p_i).
struct PendingExchanges {
  AlignedDoubles columns;        ///< e_i, kPanel x stride
  Eigen::Index row[kPanel];      ///< basis row of exchange i
  double inverse[kPanel];        ///< 1 / (entering column at row[i])
  double solve[kPanel][kPanel];  ///< column-major: p = sum_j solve[j] s_j, s_j = c[row[j]]
  int count = 0;                 ///< exchanges recorded
  Eigen::Index stride = 0;       ///< doubles per column

  /// Records exchange count: the entering column (stride doubles) at basis row j_row. The
  /// exchanges' p_i = inverse_i (s_i - sum_{l<i} e_l[row_i] p_l) are linear in s (a lower
  /// triangular map, kept by column so that applying it is eight-wide); its row i follows from
  /// the rows before it.
  void add(const double* entering, Eigen::Index j_row) {
    double* e = columns.data() + count * stride;
    std::copy(entering, entering + stride, e);
    const int i = count;
    inverse[i] = 1.0 / e[j_row];
    e[j_row] -= 1.0;
    row[i] = j_row;
    for (int j = 0; j < kPanel; ++j) {
      double v = j == i ? 1.0 : 0.0;
      for (int l = 0; l < i; ++l) v -= columns[l * stride + j_row] * solve[j][l];
      solve[j][i] = j <= i ? v * inverse[i] : 0.0;
    }
    ++count;
  }
};

/// Applies the pending exchanges, in order, to tableau columns [begin, end): per column the
/// p_i from a small triangular solve (p_i = inverse_i (c[row_i] - sum_{l<i} e_l[row_i] p_l)),
/// then c -= sum_i e_i p_i in one pass: count multiply-adds per load and store instead of one.
CARAT_MULTIVERSION_WIDE
void apply_exchanges(Tableau& F, Eigen::Index begin, Eigen::Index end, const PendingExchanges& x) {
  const Eigen::Index stride = F.stride;
  const int count = x.count;
  const double* __restrict e = x.columns.data();
  // Four columns per pass where there are four (each exchange column load serves all four).
  // Inlined always: a lambda does not inherit the target clone of the function around it.
  const auto pass = [&]<int M>(Eigen::Index c, std::integral_constant<int, M>)
      __attribute__((always_inline)) {
    // p = solve s as eight-wide multiply-adds over solve's columns.
    static_assert(kPanel == 8, "p is one v8d");
    double p[M][kPanel];
    for (int q = 0; q < M; ++q) {
      const double* column = F.col(c + q);
      v8d pv = v8d{} * 0.0;
      for (int j = 0; j < count; ++j) {
        v8d sj;
        __builtin_memcpy(&sj, &x.solve[j][0], sizeof(sj));
        pv += sj * column[x.row[j]];
      }
      __builtin_memcpy(&p[q][0], &pv, sizeof(pv));
    }
    for (Eigen::Index r = 0; r < stride; r += 8) {
      v8d v[M];
      for (int q = 0; q < M; ++q) __builtin_memcpy(&v[q], F.col(c + q) + r, sizeof(v8d));
      for (int i = 0; i < count; ++i) {
        v8d ei;
        __builtin_memcpy(&ei, e + i * stride + r, sizeof(ei));
        for (int q = 0; q < M; ++q) v[q] -= ei * p[q][i];
      }
      for (int q = 0; q < M; ++q) __builtin_memcpy(F.col(c + q) + r, &v[q], sizeof(v8d));
    }
  };
  Eigen::Index c = begin;
  for (; c + 4 <= end; c += 4) pass(c, std::integral_constant<int, 4>{});
  for (; c < end; ++c) pass(c, std::integral_constant<int, 1>{});
}

/// Row l of T = (the points' coordinate l - its weighted mean) / max |that| over the n points (0
/// when the coordinate is constant), for l < L; eight-wide partial sums in a fixed order. The
/// largest |p_i - mean| is the larger of pmax - mean and mean - pmin (rounding is monotone and
/// symmetric), so one pass finds the mean and the range and one more writes the row. Points not
/// laid out coordinate by coordinate are gathered into T's row first. T's rows hold stride_t
/// doubles (a multiple of 8, zero past n, and stay so).
CARAT_MULTIVERSION_WIDE
void centre_and_scale(const double* points, Eigen::Index L, Eigen::Index n,
                      const PointLayout& layout, const double* __restrict w, double total,
                      double* T, Eigen::Index stride_t) {
  const Eigen::Index whole = n / 8 * 8;
  const bool direct = layout.point_stride == 1 && layout.point_scale == nullptr;
  constexpr double inf = std::numeric_limits<double>::infinity();
  for (Eigen::Index l = 0; l < L; ++l) {
    double* t = T + l * stride_t;
    const double* p = points + l * layout.coordinate_stride;
    if (!direct) {
      const Eigen::Index step = layout.point_stride;
      if (layout.point_scale != nullptr) {
        for (Eigen::Index i = 0; i < n; ++i) t[i] = p[i * step] * layout.point_scale[i];
      } else {
        for (Eigen::Index i = 0; i < n; ++i) t[i] = p[i * step];
      }
      p = t;  // centred in place below
    }
    v8d acc = v8d{} * 0.0;
    v8d high = v8d{} - inf;
    v8d low = v8d{} + inf;
    for (Eigen::Index i = 0; i < whole; i += 8) {
      v8d pv;
      v8d wv;
      __builtin_memcpy(&pv, p + i, sizeof(pv));
      __builtin_memcpy(&wv, w + i, sizeof(wv));
      acc += pv * wv;
      high = pv > high ? pv : high;
      low = pv < low ? pv : low;
    }
    double mean = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
    double pmax = high[0];
    double pmin = low[0];
    for (int q = 1; q < 8; ++q) {
      pmax = std::max(pmax, high[q]);
      pmin = std::min(pmin, low[q]);
    }
    for (Eigen::Index i = whole; i < n; ++i) {
      mean += p[i] * w[i];
      pmax = std::max(pmax, p[i]);
      pmin = std::min(pmin, p[i]);
    }
    mean /= total;
    const double scale = std::max(pmax - mean, mean - pmin);
    // Constant coordinates are only centred (to zeros).
    const double inverse = scale > 0.0 ? 1.0 / scale : 1.0;
    for (Eigen::Index i = 0; i < whole; i += 8) {
      v8d pv;
      __builtin_memcpy(&pv, p + i, sizeof(pv));
      const v8d d = (pv - mean) * inverse;
      __builtin_memcpy(t + i, &d, sizeof(d));
    }
    for (Eigen::Index i = whole; i < n; ++i) t[i] = (p[i] - mean) * inverse;
  }
}

/// solve_square on the augmented matrix [A, b] held as rows (row_of[r], stride doubles each,
/// zero past column n): forward elimination with the rows below each pivot updated eight
/// columns at a time from the pivot's block on, then back substitution.
CARAT_MULTIVERSION_WIDE
bool solve_rows(double** row_of, Eigen::Index n, Eigen::Index stride, double* x) {
  for (Eigen::Index k = 0; k < n; ++k) {
    Eigen::Index best = k;
    double best_abs = std::abs(row_of[k][k]);
    for (Eigen::Index r = k + 1; r < n; ++r) {
      const double a = std::abs(row_of[r][k]);
      if (a > best_abs) {
        best_abs = a;
        best = r;
      }
    }
    if (!(best_abs > 0.0)) return false;
    std::swap(row_of[k], row_of[best]);
    const double* __restrict pivot = row_of[k];
    const double inverse = 1.0 / pivot[k];
    const Eigen::Index begin = (k + 1) / 8 * 8;
    for (Eigen::Index r = k + 1; r < n; ++r) {
      double* __restrict row = row_of[r];
      const double f = row[k] * inverse;
      if (f == 0.0) continue;
      // Columns before k + 1 in the first block are not read again.
      for (Eigen::Index c = begin; c < stride; c += 8) {
        v8d v;
        v8d p;
        __builtin_memcpy(&v, row + c, sizeof(v));
        __builtin_memcpy(&p, pivot + c, sizeof(p));
        v -= f * p;
        __builtin_memcpy(row + c, &v, sizeof(v));
      }
    }
  }
  for (Eigen::Index k = n - 1; k >= 0; --k) {
    const double* row = row_of[k];
    double sum = row[n];
    for (Eigen::Index c = k + 1; c < n; ++c) sum -= row[c] * x[c];
    x[k] = sum / row[k];
    if (!std::isfinite(x[k])) return false;
  }
  return true;
}

}  // namespace

bool solve_square(const double* A, Eigen::Index n, const double* b, double* x) {
  // Scratch of this thread, reused (see eliminate).
  thread_local AlignedDoubles rows;
  thread_local std::vector<double*> row_of;
  const Eigen::Index stride = (n + 1 + 7) / 8 * 8;
  rows.assign(static_cast<std::size_t>(n * stride), 0.0);
  row_of.resize(static_cast<std::size_t>(n));
  for (Eigen::Index r = 0; r < n; ++r)
    row_of[static_cast<std::size_t>(r)] = rows.data() + r * stride;
  for (Eigen::Index c = 0; c < n; ++c) {
    for (Eigen::Index r = 0; r < n; ++r)
      rows[static_cast<std::size_t>(r * stride + c)] = A[c * n + r];
  }
  for (Eigen::Index r = 0; r < n; ++r) rows[static_cast<std::size_t>(r * stride + n)] = b[r];
  return solve_rows(row_of.data(), n, stride, x);
}

const std::vector<char>& eliminate(const double* points, Eigen::Index L, Eigen::Index n,
                                   const PointLayout& layout, double* weights,
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
  centre_and_scale(points, L, n, layout, weights, total, T.row(0), T.stride);
  double* ones = T.row(L);
  for (Eigen::Index i = 0; i < n; ++i) ones[i] = 1.0;

  // Reduced row echelon form: basic columns (one per pivot row) and free columns. Free column f
  // gives the null vector v = e_f - sum_r T(r, f) e_{basic(r)} of the points' [p; 1].
  thread_local std::vector<Eigen::Index> pivot_col, free_col;
  thread_local std::vector<double*> row_of;
  const Eigen::Index rank = gauss_jordan(T, 1e-11, pivot_col, free_col, row_of);
  const auto m = static_cast<Eigen::Index>(free_col.size());
  if (m == 0) return alive;

  // The free columns as a column-major tableau F (rank x m): column k stays valid for the
  // current basis as points leave and free points enter it.
  thread_local Tableau F;
  F.resize(rank, m);
  copy_tableau(row_of.data(), rank, free_col, F);
  thread_local std::vector<Eigen::Index> basic;
  basic.assign(pivot_col.begin(), pivot_col.end());
  // The basis points' weights by basis row (padding rows stay 0), written back at the end.
  thread_local AlignedDoubles bw, ratio;
  bw.assign(static_cast<std::size_t>(F.stride), 0.0);
  ratio.resize(static_cast<std::size_t>(F.stride));
  for (Eigen::Index r = 0; r < rank; ++r)
    bw[static_cast<std::size_t>(r)] = weights[basic[static_cast<std::size_t>(r)]];

  long rows = 0;
  for (Eigen::Index i = 0; i < n; ++i) rows += size_of(i);
  // Exchanges are applied to the later columns kPanel at a time; column k first gets the ones
  // still pending.
  thread_local PendingExchanges pending;
  pending.columns.resize(static_cast<std::size_t>(kPanel * F.stride));
  pending.stride = F.stride;
  pending.count = 0;
  for (Eigen::Index k = 0; k < m; ++k) {
    const Eigen::Index f = free_col[static_cast<std::size_t>(k)];
    if (pending.count > 0) apply_exchanges(F, k, k + 1, pending);
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
    if (k + 1 == m) break;
    pending.add(F.col(k), j_row);
    if (pending.count == kPanel) {
      apply_exchanges(F, k + 1, m, pending);
      pending.count = 0;
      interruption_point();
    }
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
