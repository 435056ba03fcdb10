#pragma once

// Internal: what linearizing the blocks produces, per block: b and H, H stored as its lower
// triangle packed by columns (half the memory of the full matrix).

#include <cstddef>
#include <vector>

#include "huge_pages.hpp"

namespace carat::internal {

/// Per-block linearization storage for every block: H (D x D, symmetric; its lower triangle
/// packed by columns, column c holding rows c..D-1: D (D + 1) / 2 numbers) and b (D).
struct BlockLinearizations {
  std::vector<std::size_t> h_offset;  ///< start of block i's packed H in h
  std::vector<std::size_t> b_offset;  ///< start of block i's b in b
  std::vector<int> dim;               ///< D of block i
  HugeVector<double> h;               ///< all blocks' H
  HugeVector<double> b;               ///< all blocks' b
  std::vector<double> cost;           ///< 1/2 rho(s) per block
};

/// Offset of column c in a D x D lower triangle packed by columns.
inline std::size_t packed_column(std::size_t D, std::size_t c) { return c * (2 * D - c + 1) / 2; }

/// out(r, c) += H(row0 + r, col0 + c) for r < rows, c < cols (out column-major, leading
/// dimension ld), H packed as above; the row and column ranges are the same variable's
/// (the whole block is added) or two different variables' (disjoint ranges). kRows / kCols > 0
/// fix rows / cols at compile time (for the hot loops); 0 takes them at run time.
template <int kRows = 0, int kCols = 0>
inline void add_packed_block(const double* H, std::size_t D, std::size_t row0, std::size_t col0,
                             int rows, int cols, double* out, std::size_t ld) {
  const auto R = static_cast<std::size_t>(kRows > 0 ? kRows : rows);
  const auto C = static_cast<std::size_t>(kCols > 0 ? kCols : cols);
  if (row0 > col0) {  // below the diagonal: each column is contiguous
    for (std::size_t c = 0; c < C; ++c) {
      const double* src = H + packed_column(D, col0 + c) + (row0 - col0 - c);
      for (std::size_t r = 0; r < R; ++r) out[c * ld + r] += src[r];
    }
  } else if (row0 < col0) {  // above: H(i, j) = H(j, i), rows of the lower triangle
    for (std::size_t r = 0; r < R; ++r) {
      const double* src = H + packed_column(D, row0 + r) + (col0 - row0 - r);
      for (std::size_t c = 0; c < C; ++c) out[c * ld + r] += src[c];
    }
  } else {  // a diagonal block, both triangles
    for (std::size_t c = 0; c < C; ++c) {
      const double* src = H + packed_column(D, col0 + c);
      out[c * ld + c] += src[0];
      for (std::size_t r = c + 1; r < R; ++r) {
        out[c * ld + r] += src[r - c];
        out[r * ld + c] += src[r - c];
      }
    }
  }
}

}  // namespace carat::internal
