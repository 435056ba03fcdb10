#pragma once

// Internal: the Schur complement's scatter kernels. A block of a few Jacobian rows ("direct",
// see SchurLinearization) is scattered straight from its rows into V, the point's gradient, W
// and its camera's slot, without forming its D x D H. The templates are always inlined into the
// fused linearization's loops; the fixed-size entry points are built for several instruction
// sets (carat/base/multiversion.hpp).

#include <cstddef>
#include <cstring>

namespace carat::internal {

/// The contributions of a direct block (see SchurLinearization) from its n Jacobian rows J (n x D,
/// row-major) and residuals r: V += J_p^T J_p, g_p += J_p^T r and, with a camera, W += J_c^T J_p
/// (W = J_c^T J_p with kAssignW: the edge's only contribution, W not zeroed first), the lower
/// triangle of slot += J_c^T J_c, slot gradient += J_c^T r. Each output element sums over the
/// rows first and touches memory once.
template <int DC, int DP, int N = 0, bool kAssignW = false>
__attribute__((always_inline)) inline void scatter_rows(const double* __restrict J,
                                                        const double* __restrict r, int rows, int D,
                                                        int pt_local, int cam_local, int dc, int dp,
                                                        double* __restrict V, double* __restrict g,
                                                        double* __restrict W,
                                                        double* __restrict slot) {
  const int C = DC > 0 ? DC : dc;
  const int P = DP > 0 ? DP : dp;
  const int n = N > 0 ? N : rows;
  const auto row = [&](int k) { return J + k * D; };
  for (int b = 0; b < P; ++b) {
    for (int a = 0; a < P; ++a) {
      double sum = 0.0;
      for (int k = 0; k < n; ++k) sum += row(k)[pt_local + a] * row(k)[pt_local + b];
      V[b * P + a] += sum;
    }
    double sum = 0.0;
    for (int k = 0; k < n; ++k) sum += row(k)[pt_local + b] * r[k];
    g[b] += sum;
  }
  if (cam_local < 0) return;
  for (int b = 0; b < P; ++b) {
    for (int a = 0; a < C; ++a) {
      double sum = 0.0;
      for (int k = 0; k < n; ++k) sum += row(k)[cam_local + a] * row(k)[pt_local + b];
      if constexpr (kAssignW) {
        W[b * C + a] = sum;
      } else {
        W[b * C + a] += sum;
      }
    }
  }
  for (int b = 0; b < C; ++b) {  // the lower triangle (gather_cameras() mirrors it)
    for (int a = b; a < C; ++a) {
      double sum = 0.0;
      for (int k = 0; k < n; ++k) sum += row(k)[cam_local + a] * row(k)[cam_local + b];
      slot[b * C + a] += sum;
    }
  }
  double* slot_g = slot + C * C;
  for (int a = 0; a < C; ++a) {
    double sum = 0.0;
    for (int k = 0; k < n; ++k) sum += row(k)[cam_local + a] * r[k];
    slot_g[a] += sum;
  }
}

// The helpers below pass 32-byte vectors by value; they are always inlined into the kernels
// (never called across a translation unit), so the compilers' note on the AVX calling convention
// does not apply.
#if defined(__clang__)
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wpsabi"
#elif defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

/// Four doubles as one vector (GCC / Clang vector extension; unaligned loads and stores).
using Double4 = double __attribute__((vector_size(32), aligned(8)));

__attribute__((always_inline)) inline Double4 load4(const double* p) {
  Double4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
__attribute__((always_inline)) inline void store4(double* p, Double4 v) {
  std::memcpy(p, &v, sizeof(v));
}

/// column[0, 9) (+)= x0 * y0 + x1 * y1, x0 / x1 two 9-vectors held as two Double4 and a tail.
template <bool kAssign>
__attribute__((always_inline)) inline void update_column_9(double* __restrict column,
                                                           const Double4 (&x0)[2], double x0_8,
                                                           const Double4 (&x1)[2], double x1_8,
                                                           double y0, double y1) {
  for (int h = 0; h < 2; ++h) {
    const Double4 sum = x0[h] * y0 + x1[h] * y1;
    store4(column + 4 * h, kAssign ? sum : load4(column + 4 * h) + sum);
  }
  const double tail = x0_8 * y0 + x1_8 * y1;
  column[8] = kAssign ? tail : column[8] + tail;
}

/// scatter_rows<9, 3, 2> for the common layout: two rows of 12 columns, the camera's 9 first,
/// the point's 3 last. The slot's whole 9 x 9 block is summed (whole columns vectorize; its
/// upper triangle is not read).
template <bool kAssignW>
__attribute__((always_inline)) inline void scatter_two_rows_9_3(
    const double* __restrict J, const double* __restrict r, double* __restrict V,
    double* __restrict g, double* __restrict W, double* __restrict slot) {
  const double* j0 = J;
  const double* j1 = J + 12;
  const double* p0 = j0 + 9;
  const double* p1 = j1 + 9;
  for (int b = 0; b < 3; ++b) {
    for (int a = 0; a < 3; ++a) V[b * 3 + a] += p0[a] * p0[b] + p1[a] * p1[b];
    g[b] += p0[b] * r[0] + p1[b] * r[1];
  }
  const Double4 c0[2] = {load4(j0), load4(j0 + 4)};
  const Double4 c1[2] = {load4(j1), load4(j1 + 4)};
  for (int b = 0; b < 3; ++b) {
    update_column_9<kAssignW>(W + b * 9, c0, j0[8], c1, j1[8], p0[b], p1[b]);
  }
  for (int b = 0; b < 9; ++b) {
    update_column_9<false>(slot + b * 9, c0, j0[8], c1, j1[8], j0[b], j1[b]);
  }
  update_column_9<false>(slot + 81, c0, j0[8], c1, j1[8], r[0], r[1]);
}

#if defined(__clang__)
#pragma clang diagnostic pop
#elif defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

/// scatter_rows for cameras of 9 and points of 3: the two-row [camera, point] layout through
/// scatter_two_rows_9_3, other layouts through scatter_rows<9, 3>; assign_w: W = (not +=).
void scatter_rows_9_3(const double* J, const double* r, int n, int D, int pt_local, int cam_local,
                      double* V, double* g, double* W, double* slot, bool assign_w);

/// The points [p0, p1) of a standard chunk (see SchurLinearization): per point, V zeroed, then
/// each block q of it (rows at J + 26 (q - q_begin[p0])) scattered by scatter_two_rows_9_3 into
/// V, the point's gradient, its edge's W and its edge's slot.
void scatter_standard_chunk_9_3(std::size_t p0, std::size_t p1, const std::size_t* q_begin,
                                const std::size_t* edge_of_q, const std::size_t* w_offset,
                                const std::size_t* slot_of_edge, const std::size_t* v_offset,
                                const int* pt_offset, const double* J, double* v, double* gradient,
                                double* w, double* slots);

/// scatter_rows for cameras of 6 and points of 3 (two rows or any).
void scatter_rows_6_3(const double* J, const double* r, int n, int D, int pt_local, int cam_local,
                      double* V, double* g, double* W, double* slot, bool assign_w);

}  // namespace carat::internal
