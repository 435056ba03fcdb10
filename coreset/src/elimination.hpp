#pragma once

// Internal: Caratheodory elimination on a small weighted point set.

#include <Eigen/Core>
#include <span>
#include <vector>

namespace carat::internal {

/// Where coordinate l of point i lies: points[l * coordinate_stride + i * point_stride], times
/// point_scale[i] when that is given (coordinate-major: {stride}; item-major: {1, L}).
struct PointLayout {
  Eigen::Index coordinate_stride = 0;   ///< doubles from one coordinate to the next
  Eigen::Index point_stride = 1;        ///< doubles from one point to the next
  const double* point_scale = nullptr;  ///< per-point factor (null: 1)
};

/// Eliminates points of a set of n points in dimension L (laid out as `layout` says) along null
/// vectors of [points; 1]: one Gauss-Jordan factorization, then per step a ratio test (the
/// smallest w_i / v_i over v_i > 0) that zeroes one weight, and a basis exchange that keeps the
/// remaining null vectors valid. Weights stay >= 0 and keep sum(w) and sum(w_i p_i). `sizes[i]`
/// is how many rows point i stands for (empty: 1 each); elimination stops before the rows of
/// the survivors would drop below `min_rows`. Returns the survivor mask (scratch of this thread:
/// valid until its next call); `weights` (n) holds the new weights.
const std::vector<char>& eliminate(const double* points, Eigen::Index L, Eigen::Index n,
                                   const PointLayout& layout, double* weights,
                                   std::span<const long> sizes, long min_rows);

/// Solves A x = b for a square A (n x n, column-major) by an LU factorization with partial
/// pivoting. Returns false (x unspecified) when A has a zero pivot or x is not finite.
bool solve_square(const double* A, Eigen::Index n, const double* b, double* x);

}  // namespace carat::internal
