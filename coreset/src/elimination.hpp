#pragma once

// Internal: Caratheodory elimination on a small weighted point set.

#include <Eigen/Core>
#include <span>
#include <vector>

namespace carat::internal {

/// Eliminates points of `points` (L x n) along null vectors of [points; 1]: one kernel
/// computation, then per step a ratio test (the smallest w_i / v_i over v_i > 0) that zeroes one
/// weight, and a rank-1 update that zeroes that point's entry in the remaining null vectors.
/// Weights stay >= 0 and keep sum(w) and sum(w_i p_i). `sizes[i]` is how many rows point i
/// stands for (empty: 1 each); elimination stops before the rows of the survivors would drop
/// below `min_rows`. Returns the survivor mask; `weights` holds the new weights.
std::vector<char> eliminate(const Eigen::MatrixXd& points, Eigen::VectorXd& weights,
                            std::span<const long> sizes, long min_rows);

}  // namespace carat::internal
