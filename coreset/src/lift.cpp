#include "lift.hpp"

#include <algorithm>
#include <type_traits>
#include <utility>
#include <vector>

#include "simd.hpp"

namespace carat::internal {
namespace {

/// Integer vectors of V's shape (the condition of a lane blend).
template <class V>
struct LaneMask;
template <>
struct LaneMask<v4d> {
  typedef long type __attribute__((vector_size(32)));
};
template <>
struct LaneMask<v8d> {
  typedef long type __attribute__((vector_size(64)));
};

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
/// The r = 6 kernel: per row, two 4-wide outer-product updates, lo[j] += x_j [x0..x3] for
/// j < 3 and hi[j] += x_j [x3, x4, x5, e] for all j, which cover the 28 products x_j x_k
/// (j <= k) with 10 multiply-adds. The matrix's last row (of `rows`) builds its vectors element
/// by element: the 4-wide load from a + 3 would read one double past it.
/// The condition that picks lane 3 of a v4d.
constexpr LaneMask<v4d>::type kLastLane = {0, 0, 0, -1};

__attribute__((always_inline)) inline void accumulate_6(const double* J, const double* e, long rows,
                                                        long begin, long end, v4d* lo, v4d* hi) {
  const long vector_end = std::min(end, rows - 1);
  for (long i = begin; i < vector_end; ++i) {
    const double* a = J + i * 6;
    v4d x_lo;
    v4d x_hi;
    __builtin_memcpy(&x_lo, a, sizeof(x_lo));
    __builtin_memcpy(&x_hi, a + 3, sizeof(x_hi));
    x_hi = kLastLane ? v4d{} + e[i] : x_hi;  // a blend in registers (see load_block)
    for (int j = 0; j < 3; ++j) lo[j] += a[j] * x_lo;
    for (int j = 0; j < 6; ++j) hi[j] += a[j] * x_hi;
    hi[6] += e[i] * x_hi;
  }
  if (vector_end < end) {
    const double* a = J + vector_end * 6;
    const double ev = e[vector_end];
    const v4d x_lo = {a[0], a[1], a[2], a[3]};
    const v4d x_hi = {a[3], a[4], a[5], ev};
    for (int j = 0; j < 3; ++j) lo[j] += a[j] * x_lo;
    for (int j = 0; j < 6; ++j) hi[j] += a[j] * x_hi;
    hi[6] += ev * x_hi;
  }
}

/// Writes the ten accumulators of the r = 6 scheme (lo[j] = x_j [x0..x3] for j < 3, hi[j] =
/// x_j [x3, x4, x5, e]) to out[0, 28) in lift order with ten overlapping 4-wide stores instead of
/// 28 lane extracts: each store's lanes that fall outside its place hold either the very same
/// product (x_j x3 is in both lo[j][3] and hi[j][0]) or are overwritten by a later store.
__attribute__((always_inline)) inline void store_lift_6(const v4d* lo, const v4d* hi, double* out) {
  __builtin_memcpy(out + 24, &hi[6], sizeof(v4d));  // [27] = e e
  __builtin_memcpy(out + 23, &hi[5], sizeof(v4d));  // [25, 26] = x5 x5, x5 e
  __builtin_memcpy(out + 21, &hi[4], sizeof(v4d));  // [22, 24]
  __builtin_memcpy(out + 18, &hi[3], sizeof(v4d));  // [18, 21]
  __builtin_memcpy(out + 14, &hi[2], sizeof(v4d));  // [15, 17]
  __builtin_memcpy(out + 11, &lo[2], sizeof(v4d));  // [13, 14]
  __builtin_memcpy(out + 9, &hi[1], sizeof(v4d));   // [10, 12]
  __builtin_memcpy(out + 6, &lo[1], sizeof(v4d));   // [7, 9]
  __builtin_memcpy(out + 3, &hi[0], sizeof(v4d));   // [4, 6]
  __builtin_memcpy(out + 0, &lo[0], sizeof(v4d));   // [0, 3]
}

/// Sum of the lifts of rows [begin, end) for r = 6.
CARAT_MULTIVERSION
void lift_sum_6(const double* J, const double* e, long rows, long begin, long end, double* out) {
  v4d lo[3] = {};
  v4d hi[7] = {};
  accumulate_6(J, e, rows, begin, end, lo, hi);
  store_lift_6(lo, hi, out);
}

/// Chunk sums for r = 6 in one call: each chunk's accumulators stored with store_lift_6 and
/// added to running totals lane by lane (the same additions, in the same order, as adding each
/// chunk's 28 sums to total). A call per 32-row chunk and 28 lane extracts per chunk had cost as
/// much as the rows themselves.
CARAT_MULTIVERSION
void lift_chunk_sums_6(const double* J, const double* e, long rows, long chunk_rows,
                       const int* position, double* out, double* total) {
  constexpr int L = lifted_dim(6);
  const long chunks = (rows + chunk_rows - 1) / chunk_rows;
  v4d total_lo[3] = {};
  v4d total_hi[7] = {};
  for (long c = 0; c < chunks; ++c) {
    const long begin = c * chunk_rows;
    v4d lo[3] = {};
    v4d hi[7] = {};
    accumulate_6(J, e, rows, begin, std::min(rows, begin + chunk_rows), lo, hi);
    store_lift_6(lo, hi, out + static_cast<long>(position[c]) * L);
    for (int j = 0; j < 3; ++j) total_lo[j] += lo[j];
    for (int j = 0; j < 7; ++j) total_hi[j] += hi[j];
  }
  double sums[L];
  store_lift_6(total_lo, total_hi, sums);
  for (int l = 0; l < L; ++l) total[l] += sums[l];
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

/// Lift accumulators of x = [a, e] with NX = r + 1 entries, by column of x^T x, in vectors V of
/// W lanes: block q (x[Wq, Wq + W)) has an accumulator for every column k >= Wq, acc += x_k
/// x[Wq, Wq + W), so that x_j x_k (j <= k) is lane j - Wq of block q = j / W's column k. Each x_k
/// is one broadcast from memory; the accumulators stay in registers (18 eight-wide ones for
/// r = 12). Lanes past x's end hold products nobody reads.
template <int NX, class V>
struct LiftAccumulators {
  static constexpr int W = sizeof(V) / sizeof(double);
  static constexpr int kBlocks = (NX + W - 1) / W;
  /// Index of block q's accumulator for column k (k >= W q).
  static constexpr int slot(int q, int k) { return q * NX - W * q * (q - 1) / 2 + (k - W * q); }
  static constexpr int kCount = slot(kBlocks - 1, NX - 1) + 1;
  V acc[kCount];

  __attribute__((always_inline)) void zero() {
    for (auto& v : acc) v = V{} * 0.0;
  }
  /// Adds x_k (w x) for the row whose entries are x(k) and whose weighted blocks are xb[q].
  template <class Entry>
  __attribute__((always_inline)) void add(const Entry& x, const V* xb) {
#pragma GCC unroll 16
    for (int q = 0; q < kBlocks; ++q) {
#pragma GCC unroll 16
      for (int k = W * q; k < NX; ++k) acc[slot(q, k)] += x(k) * xb[q];
    }
  }
  /// Writes the L = NX (NX + 1) / 2 sums in lift order.
  __attribute__((always_inline)) void store(double* out) const {
    double tile[NX][kBlocks * W];  // tile[k][j] = sum of x_j x_k (j <= k)
    for (int q = 0; q < kBlocks; ++q) {
      for (int k = W * q; k < NX; ++k)
        __builtin_memcpy(&tile[k][W * q], &acc[slot(q, k)], sizeof(V));
    }
    // Unrolled element copies: a loop here becomes a call to memcpy per row, whose start-up
    // cost was most of the time of a small cluster.
    int idx = 0;
#pragma GCC unroll 16
    for (int j = 0; j < NX; ++j) {
#pragma GCC unroll 16
      for (int k = j; k < NX; ++k) out[idx++] = tile[k][j];
    }
  }
};

/// Block q of a row x = [a[0, R), e]: W doubles from a + Wq (the caller makes sure they can be
/// read), with e in lane R - Wq when the block holds x's last entry.
template <int R, class V, int Q>
__attribute__((always_inline)) inline void load_block(const double* a, double e, V& out) {
  constexpr int W = sizeof(V) / sizeof(double);
  __builtin_memcpy(&out, a + W * Q, sizeof(V));
  if constexpr (R >= W * Q && R < W * (Q + 1)) {
    // A blend with the broadcast e, in registers: writing the lane through memory and reading the
    // whole vector back stalls on store forwarding (most of a small row's time).
    typename LaneMask<V>::type lane = {};
    lane[R - W * Q] = -1;
    const V broadcast = V{} + e;
    out = lane ? broadcast : out;
  }
}

/// Chunk sums of consecutive rows (as lift_chunk_sums) with the accumulators above.
template <int NX>
__attribute__((always_inline)) inline void chunk_sums_body(const double* J, const double* e,
                                                           long rows, long chunk_rows,
                                                           const int* position, double* out,
                                                           double* total) {
  constexpr int R = NX - 1;
  constexpr int L = lifted_dim(R);
  using V = v8d;  // four-wide, r = 12 needs 28 accumulators, which spilled
  using Acc = LiftAccumulators<NX, V>;
  constexpr int W = Acc::W;
  const long chunks = (rows + chunk_rows - 1) / chunk_rows;
  Acc acc;
  Acc sum_of_chunks;  // the total, added chunk by chunk in the accumulators' layout
  sum_of_chunks.zero();
  for (long c = 0; c < chunks; ++c) {
    acc.zero();
    const long end = std::min(rows, (c + 1) * chunk_rows);
    for (long i = c * chunk_rows; i < end; ++i) {
      const double* a = J + i * R;
      const double ei = e[i];
      const auto x = [&](int j) __attribute__((always_inline)) { return j < R ? a[j] : ei; };
      V xb[Acc::kBlocks] = {};
      if (i * R + Acc::kBlocks * W <= rows * R) {
        // Whole-vector loads (reading past the row, never past the matrix) through a copy of
        // the pointer the compiler cannot see through, so that each x_k stays a broadcast from
        // memory (otherwise it becomes a lane permute of a loaded vector, and permutes have
        // one port where broadcasts have two).
        const double* opaque = a;
        asm("" : "+r"(opaque));
        [&]<int... Q>(std::integer_sequence<int, Q...>) {
          (load_block<R, V, Q>(opaque, ei, xb[Q]), ...);
        }
        (std::make_integer_sequence<int, Acc::kBlocks>{});
      } else {
        for (int q = 0; q < Acc::kBlocks; ++q) {
          for (int k = 0; k < W && W * q + k < NX; ++k) xb[q][k] = x(W * q + k);
        }
      }
      acc.add(x, xb);
    }
    acc.store(out + static_cast<long>(position[c]) * L);
    for (int k = 0; k < Acc::kCount; ++k) sum_of_chunks.acc[k] += acc.acc[k];
  }
  double sums[L];
  sum_of_chunks.store(sums);
  for (int l = 0; l < L; ++l) total[l] += sums[l];
}

/// Weighted cluster sums of packed rows (as packed_cluster_sums) with the accumulators above.
template <int NX>
__attribute__((always_inline)) inline void packed_sums_body(const double* X, const double* w,
                                                            const int* begin, int clusters,
                                                            double* out) {
  constexpr int P = packed_stride(NX - 1);
  constexpr int L = lifted_dim(NX - 1);
  using V = v8d;  // four-wide, r = 12 needs 28 accumulators, which spilled
  using Acc = LiftAccumulators<NX, V>;
  constexpr int W = Acc::W;
  static_assert(Acc::kBlocks * W <= P, "blocks stay inside a packed row");
  Acc acc;
  for (int c = 0; c < clusters; ++c) {
    acc.zero();
    for (int i = begin[c]; i < begin[c + 1]; ++i) {
      const double* row = X + static_cast<long>(i) * P;
      const auto x = [&](int j) __attribute__((always_inline)) { return row[j]; };
      const double* opaque = row;  // as in chunk_sums_body: x_k stays a memory broadcast
      asm("" : "+r"(opaque));
      V xb[Acc::kBlocks];
      for (int q = 0; q < Acc::kBlocks; ++q) {
        __builtin_memcpy(&xb[q], opaque + W * q, sizeof(V));
        xb[q] *= w[i];
      }
      acc.add(x, xb);
    }
    acc.store(out + static_cast<long>(c) * L);
  }
}

/// chunk_sums_body for the row width NX, as a type (for dispatch_cols).
template <int NX>
struct ChunkSums {
  __attribute__((always_inline)) static void run(const double* J, const double* e, long rows,
                                                 long chunk_rows, const int* position, double* out,
                                                 double* total) {
    chunk_sums_body<NX>(J, e, rows, chunk_rows, position, out, total);
  }
};

/// packed_sums_body for the row width NX, as a type (for dispatch_cols).
template <int NX>
struct PackedSums {
  __attribute__((always_inline)) static void run(const double* X, const double* w, const int* begin,
                                                 int clusters, double* out) {
    packed_sums_body<NX>(X, w, begin, clusters, out);
  }
};

/// Body<nx>::run(args...) for nx in [NX, kMaxPackedCols], inlined into the caller so that its
/// target (AVX-512 or not) applies to the body.
template <template <int> class Body, int NX = 2, class... Args>
__attribute__((always_inline)) inline void dispatch_cols(int nx, Args... args) {
  if constexpr (NX <= kMaxPackedCols) {
    if (nx == NX) {
      Body<NX>::run(args...);
      return;
    }
    dispatch_cols<Body, NX + 1>(nx, args...);
  }
}

#if !CARAT_HAVE_AVX512_PATH  // where the wide kernels run without AVX-512 (sanitized builds)
CARAT_MULTIVERSION
void chunk_sums_any(int nx, const double* J, const double* e, long rows, long chunk_rows,
                    const int* position, double* out, double* total) {
  dispatch_cols<ChunkSums>(nx, J, e, rows, chunk_rows, position, out, total);
}
#endif

CARAT_MULTIVERSION
void packed_sums_any(int nx, const double* X, const double* w, const int* begin, int clusters,
                     double* out) {
  dispatch_cols<PackedSums>(nx, X, w, begin, clusters, out);
}

#if CARAT_HAVE_AVX512_PATH
// Without SLP vectorization: it turns the x_k broadcasts from memory into permutes of a loaded
// row (one port instead of two; the accumulation ran at half speed).
CARAT_TARGET_AVX512 __attribute__((optimize("no-tree-slp-vectorize"))) void chunk_sums_512(
    int nx, const double* J, const double* e, long rows, long chunk_rows, const int* position,
    double* out, double* total) {
  dispatch_cols<ChunkSums>(nx, J, e, rows, chunk_rows, position, out, total);
}

CARAT_TARGET_AVX512 __attribute__((optimize("no-tree-slp-vectorize"))) void packed_sums_512(
    int nx, const double* X, const double* w, const int* begin, int clusters, double* out) {
  dispatch_cols<PackedSums>(nx, X, w, begin, clusters, out);
}
#endif

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

void lift_chunk_sums(const double* J, const double* e, int r, long rows, long chunk_rows,
                     const int* position, double* out, double* total) {
  if (r == 6) {
    lift_chunk_sums_6(J, e, rows, chunk_rows, position, out, total);
    return;
  }
  if (r + 1 <= kMaxPackedCols && wide_kernels()) {
#if CARAT_HAVE_AVX512_PATH
    chunk_sums_512(r + 1, J, e, rows, chunk_rows, position, out, total);
#else
    chunk_sums_any(r + 1, J, e, rows, chunk_rows, position, out, total);
#endif
    return;
  }
  const int L = lifted_dim(r);
  const long chunks = (rows + chunk_rows - 1) / chunk_rows;
  for (long c = 0; c < chunks; ++c) {
    const long begin = c * chunk_rows;
    double* o = out + static_cast<long>(position[c]) * L;
    lift_sum(J, e, r, rows, begin, std::min(rows, begin + chunk_rows), o);
    for (int l = 0; l < L; ++l) total[l] += o[l];
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

void pack_rows(const double* J, const double* e, int r, const int* ids, int count, double* X) {
  const int P = packed_stride(r);
  for (int k = 0; k < count; ++k) {
    double* x = X + static_cast<long>(k) * P;
    const double* a = J + static_cast<long>(ids[k]) * r;
    for (int j = 0; j < r; ++j) x[j] = a[j];
    x[r] = e[ids[k]];
    for (int j = r + 1; j < P; ++j) x[j] = 0.0;
  }
}

void packed_cluster_sums(const double* X, int r, const double* w, const int* begin, int clusters,
                         double* out) {
#if CARAT_HAVE_AVX512_PATH
  if (cpu_has_avx512()) {
    packed_sums_512(r + 1, X, w, begin, clusters, out);
    return;
  }
#endif
  packed_sums_any(r + 1, X, w, begin, clusters, out);  // correct anywhere, fast with AVX-512
}

void lift_packed(const double* X, int r, int count, double* out, long stride) {
  const int P = packed_stride(r);
  for (int i = 0; i < count; ++i) {
    const double* x = X + static_cast<long>(i) * P;
    long idx = 0;
    for (int j = 0; j <= r; ++j) {
      for (int k = j; k <= r; ++k) out[idx++ * stride + i] = x[j] * x[k];
    }
  }
}

}  // namespace carat::internal
