#pragma once

/// The exact quadratic coreset of least-squares rows: given Jacobian rows a_k (1 x r) and
/// residuals e_k, select M rows and weights w_k > 0 with
///   sum w_k a_k^T a_k = J^T J,   sum w_k a_k^T e_k = J^T e,   sum w_k e_k^2 = e^T e
/// to rounding. Each row is lifted to p_k = [upper(a_k^T a_k), a_k^T e_k, e_k^2] of dimension
/// L = r(r+1)/2 + r + 1 and a Caratheodory set of the rows' mean is found with a
/// Fast-Caratheodory that never materializes the L x N lifted matrix: the rows are shuffled
/// once into contiguous columns, summed in fixed chunks in one pass, and every level works on
/// chunk or row sums with one weight per surviving range.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace carat {

/// Settings of the quadratic coreset.
struct RowCoresetOptions {
  int target_rows = 0;     ///< M; 0 means the minimum L + 1 (29 for r = 6)
  int clusters = 0;        ///< K clusters per Fast-Caratheodory level (>= L + 2); 0: the default,
                           ///< default_coreset_clusters(r) = max(64, 2 (L + 1))
  std::uint64_t seed = 1;  ///< seed of the row shuffle (same seed, same rows)
  bool exact_size = true;  ///< return exactly M rows (when N > M); else at most M
};

/// Selected rows (ascending indices into the input) and their weights.
struct RowCoreset {
  std::vector<int> rows;        ///< selected row indices, ascending
  std::vector<double> weights;  ///< weight of each selected row (> 0)
};

/// Smallest valid target for reduced dimension r: r(r+1)/2 + r + 2.
int minimum_coreset_rows(int reduced_dim);

/// Clusters per level when RowCoresetOptions::clusters is 0: max(64, 2 (L + 1)) with
/// L = r(r+1)/2 + r + 1, so that each level keeps at most half of the clusters (64 for r <= 6;
/// 184 for r = 12).
int default_coreset_clusters(int reduced_dim);

/// Selects the coreset of the rows (J_r: N x r row-major, e: N). N <= M returns every row with
/// weight 1. Throws carat::Error for M below the minimum, K < L + 2, sizes that do not match,
/// a non-finite value (naming the row), or sums that overflow double. Per-thread scratch is
/// kept between calls up to 64 MiB (larger scratch is released after the call).
RowCoreset select_coreset_rows(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>&
        J_r,
    const Eigen::Ref<const Eigen::VectorXd>& e, const RowCoresetOptions& options = {});

}  // namespace carat
