#pragma once

/// Exact Caratheodory sets of weighted point sets: a subset of the points with new positive
/// weights that keeps the weighted sum and the total weight (to rounding). In dimension L at
/// most L + 1 points are needed (fewer when the points span a lower-dimensional space).

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace carat {

/// A subset of a weighted point set with its new weights.
struct WeightedSubset {
  std::vector<int> indices;     ///< indices into the input, ascending
  std::vector<double> weights;  ///< new weights (> 0), parallel to indices
};

/// Settings of the Caratheodory reductions.
struct CaratheodoryOptions {
  int clusters = 64;       ///< Fast-Caratheodory: clusters per level (K >= L + 2)
  int min_points = 0;      ///< stop eliminating at this many points (0: as few as possible)
  std::uint64_t seed = 1;  ///< Fast-Caratheodory: seed of the shuffle that forms clusters
};

/// Classic Caratheodory on `points` (L x n, one column per point) with positive `weights`:
/// eliminates points along null vectors of [points; 1] (one factorization, then ratio tests and
/// rank-1 updates of the null-space basis) until no null vector is left or min_points remain.
/// O(n^3) in n: meant for small n (use fast_caratheodory otherwise). Throws carat::Error for
/// mismatched sizes, non-finite values or non-positive weights.
WeightedSubset caratheodory(const Eigen::MatrixXd& points, std::span<const double> weights,
                            int min_points = 0);

/// Fast-Caratheodory (Maalouf et al. 2019): seeded shuffle, K contiguous clusters per level,
/// a Caratheodory set of the cluster means, recursion on the kept clusters' members; time
/// linear in n. Same guarantees and errors as caratheodory(), plus K < L + 2 is an error.
WeightedSubset fast_caratheodory(const Eigen::MatrixXd& points, std::span<const double> weights,
                                 const CaratheodoryOptions& options = {});

}  // namespace carat
