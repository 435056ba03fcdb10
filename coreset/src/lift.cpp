#include "lift.hpp"

#include <algorithm>
#include <vector>

#include "simd.hpp"

namespace carat::internal {
namespace {

typedef double v4d __attribute__((vector_size(32)));

/// Sum of the lifts of rows [begin, end), four rows per vector lane set (one partial sum per
/// lane, added in a fixed order at the end), then the last rows one by one.
template <int R>
__attribute__((always_inline)) inline void lift_sum_lanes(const double* J, const double* e,
                                                          long begin, long end, double* out) {
  constexpr int L = lifted_dim(R);
  v4d acc[L];
  for (auto& a : acc) a = v4d{0.0, 0.0, 0.0, 0.0};
  long i = begin;
  for (; i + 3 < end; i += 4) {
    const double* row = J + i * R;
    v4d x[R + 1];
    for (int j = 0; j < R; ++j) x[j] = v4d{row[j], row[R + j], row[2 * R + j], row[3 * R + j]};
    x[R] = v4d{e[i], e[i + 1], e[i + 2], e[i + 3]};
    int idx = 0;
    for (int j = 0; j <= R; ++j) {
      for (int k = j; k <= R; ++k) acc[idx++] += x[j] * x[k];
    }
  }
  for (int l = 0; l < L; ++l) out[l] = (acc[l][0] + acc[l][1]) + (acc[l][2] + acc[l][3]);
  for (; i < end; ++i) {
    double x[R + 1];
    for (int j = 0; j < R; ++j) x[j] = J[i * R + j];
    x[R] = e[i];
    int idx = 0;
    for (int j = 0; j <= R; ++j) {
      for (int k = j; k <= R; ++k) out[idx++] += x[j] * x[k];
    }
  }
}

/// Lifts of rows ids[0..count), four rows per vector, stored item-major.
template <int R>
__attribute__((always_inline)) inline void lift_rows_lanes(const double* J, const double* e,
                                                           const int* ids, int count, double* out) {
  constexpr int L = lifted_dim(R);
  int k = 0;
  for (; k + 3 < count; k += 4) {
    const double* r0 = J + static_cast<long>(ids[k]) * R;
    const double* r1 = J + static_cast<long>(ids[k + 1]) * R;
    const double* r2 = J + static_cast<long>(ids[k + 2]) * R;
    const double* r3 = J + static_cast<long>(ids[k + 3]) * R;
    v4d x[R + 1];
    for (int j = 0; j < R; ++j) x[j] = v4d{r0[j], r1[j], r2[j], r3[j]};
    x[R] = v4d{e[ids[k]], e[ids[k + 1]], e[ids[k + 2]], e[ids[k + 3]]};
    int idx = 0;
    for (int j = 0; j <= R; ++j) {
      for (int q = j; q <= R; ++q) {
        const v4d p = x[j] * x[q];
        double* o = out + static_cast<long>(k) * L + idx;
        o[0] = p[0];
        o[L] = p[1];
        o[2 * L] = p[2];
        o[3 * L] = p[3];
        ++idx;
      }
    }
  }
  for (; k < count; ++k) {
    double x[R + 1];
    for (int j = 0; j < R; ++j) x[j] = J[static_cast<long>(ids[k]) * R + j];
    x[R] = e[ids[k]];
    int idx = 0;
    for (int j = 0; j <= R; ++j) {
      for (int q = j; q <= R; ++q) out[static_cast<long>(k) * L + idx++] = x[j] * x[q];
    }
  }
}

CARAT_MULTIVERSION
void lift_sum_3(const double* J, const double* e, long begin, long end, double* out) {
  lift_sum_lanes<3>(J, e, begin, end, out);
}
/// The r = 6 kernel: per row, two 4-wide outer-product updates, lo = a[0..3] against a[0..2]
/// and hi = [a3, a4, a5, e] against all of x, which cover the 28 products x_j x_k (j <= k) with
/// 10 multiply-adds. The last row of J is done on its own (hi reads one double past a row).
CARAT_MULTIVERSION
void lift_sum_6(const double* J, const double* e, long rows, long begin, long end, double* out) {
  v4d lo[3] = {};
  v4d hi[7] = {};
  long i = begin;
  const long vector_end = std::min(end, rows - 1);
  for (; i < vector_end; ++i) {
    const double* a = J + i * 6;
    v4d x_lo;
    v4d x_hi;
    __builtin_memcpy(&x_lo, a, sizeof(x_lo));
    __builtin_memcpy(&x_hi, a + 3, sizeof(x_hi));
    x_hi[3] = e[i];
    for (int j = 0; j < 3; ++j) lo[j] += a[j] * x_lo;
    for (int j = 0; j < 6; ++j) hi[j] += a[j] * x_hi;
    hi[6] += e[i] * x_hi;
  }
  int idx = 0;
  for (int j = 0; j <= 6; ++j) {
    for (int k = j; k <= 6; ++k) out[idx++] = (j <= 2 && k <= 3) ? lo[j][k] : hi[j][k - 3];
  }
  for (; i < end; ++i) {
    double x[7];
    for (int j = 0; j < 6; ++j) x[j] = J[i * 6 + j];
    x[6] = e[i];
    idx = 0;
    for (int j = 0; j <= 6; ++j) {
      for (int k = j; k <= 6; ++k) out[idx++] += x[j] * x[k];
    }
  }
}
CARAT_MULTIVERSION
void lift_sum_12(const double* J, const double* e, long begin, long end, double* out) {
  lift_sum_lanes<12>(J, e, begin, end, out);
}
CARAT_MULTIVERSION
void lift_rows_3(const double* J, const double* e, const int* ids, int count, double* out) {
  lift_rows_lanes<3>(J, e, ids, count, out);
}
CARAT_MULTIVERSION
void lift_rows_6(const double* J, const double* e, const int* ids, int count, double* out) {
  lift_rows_lanes<6>(J, e, ids, count, out);
}
CARAT_MULTIVERSION
void lift_rows_12(const double* J, const double* e, const int* ids, int count, double* out) {
  lift_rows_lanes<12>(J, e, ids, count, out);
}

}  // namespace

void lift_sum(const double* J, const double* e, int r, long rows, long begin, long end,
              double* out) {
  switch (r) {
    case 3:
      lift_sum_3(J, e, begin, end, out);
      return;
    case 6:
      lift_sum_6(J, e, rows, begin, end, out);
      return;
    case 12:
      lift_sum_12(J, e, begin, end, out);
      return;
    default:
      break;
  }
  const int L = lifted_dim(r);
  for (int l = 0; l < L; ++l) out[l] = 0.0;
  std::vector<double> x(static_cast<std::size_t>(r) + 1);
  for (long i = begin; i < end; ++i) {
    for (int j = 0; j < r; ++j) x[static_cast<std::size_t>(j)] = J[i * r + j];
    x[static_cast<std::size_t>(r)] = e[i];
    int idx = 0;
    for (std::size_t j = 0; j < x.size(); ++j) {
      for (std::size_t k = j; k < x.size(); ++k) out[idx++] += x[j] * x[k];
    }
  }
}

void lift_rows(const double* J, const double* e, int r, const int* ids, int count, double* out) {
  switch (r) {
    case 3:
      lift_rows_3(J, e, ids, count, out);
      return;
    case 6:
      lift_rows_6(J, e, ids, count, out);
      return;
    case 12:
      lift_rows_12(J, e, ids, count, out);
      return;
    default:
      break;
  }
  std::vector<double> x(static_cast<std::size_t>(r) + 1);
  for (int k = 0; k < count; ++k) {
    for (int j = 0; j < r; ++j)
      x[static_cast<std::size_t>(j)] = J[static_cast<long>(ids[k]) * r + j];
    x[static_cast<std::size_t>(r)] = e[ids[k]];
    long idx = 0;
    for (std::size_t j = 0; j < x.size(); ++j) {
      for (std::size_t q = j; q < x.size(); ++q) {
        out[static_cast<long>(k) * lifted_dim(r) + idx++] = x[j] * x[q];
      }
    }
  }
}

}  // namespace carat::internal
