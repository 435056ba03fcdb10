#pragma once

// Internal: the lift of a least-squares row (a: 1 x r, residual e) to the L = (r+1)(r+2)/2
// products x_j x_k (j <= k) of x = [a, e]: upper(a^T a), a^T e and e^2, interleaved row by row
// of the upper triangle of x^T x. Every row's lift, or the sum over a range of rows.

namespace carat::internal {

/// Lifted dimension (r+1)(r+2)/2 for reduced dimension r.
constexpr int lifted_dim(int r) { return (r + 1) * (r + 2) / 2; }

/// Writes the sum of the lifts of rows [begin, end) to out (L doubles). J is row-major with r
/// columns and `rows` rows in all; e has one residual per row.
void lift_sum(const double* J, const double* e, int r, long rows, long begin, long end,
              double* out);

/// Sums the lifts of consecutive chunks of `chunk_rows` rows (the last one may be shorter): chunk c
/// goes to out[position[c] * L, ...) and every chunk sum is added to total[0, L) in chunk order.
void lift_chunk_sums(const double* J, const double* e, int r, long rows, long chunk_rows,
                     const int* position, double* out, double* total);

/// Writes the lift of row ids[k] to out[k * L, (k + 1) * L) (item-major), k < count.
void lift_rows(const double* J, const double* e, int r, const int* ids, int count, double* out);

/// Largest r + 1 that packed rows support.
constexpr int kMaxPackedCols = 16;

/// Doubles per packed row for r columns: r + 1 rounded up to 8 (0 when r + 1 > kMaxPackedCols).
constexpr int packed_stride(int r) { return r + 1 > kMaxPackedCols ? 0 : (r + 1 + 7) / 8 * 8; }

/// Packs rows ids[k] as x = [J row, e, 0, ...] into X[k * packed_stride(r), ...), k < count.
void pack_rows(const double* J, const double* e, int r, const int* ids, int count, double* X);

/// Weighted lifted sums of clusters of packed rows: out[c * L + l] = sum over i in
/// [begin[c], begin[c + 1]) of w[i] lift(x_i)[l], x_i the packed row i of X.
void packed_cluster_sums(const double* X, int r, const double* w, const int* begin, int clusters,
                         double* out);

/// Lifts of packed rows, coordinate-major: out[l * stride + i] = lift(x_i)[l], i < count.
void lift_packed(const double* X, int r, int count, double* out, long stride);

}  // namespace carat::internal
