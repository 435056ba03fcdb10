#pragma once

// Internal: the Fast-Caratheodory level loop over "items". An item stands for `count` rows that
// share one weight per row; `sums` holds each item's unweighted sum of lifted rows.

#include <Eigen/Core>
#include <vector>

namespace carat::internal {

/// Items of a reduction: their lifted sums, row counts and per-row weights. Storage only grows
/// (reuse one Items across calls to avoid page faults on fresh memory).
struct Items {
  Eigen::MatrixXd sums;        ///< L x capacity; columns [0, size()) are live
  std::vector<long> counts;    ///< rows per item
  std::vector<double> weight;  ///< weight of each row of the item
  std::vector<int> ids;        ///< caller's id of each item

  /// Makes room for `count` items of dimension L (contents unspecified).
  void reset(Eigen::Index L, int count);
  /// Number of items.
  int size() const { return static_cast<int>(counts.size()); }
  /// Rows represented by all items.
  long rows() const;
  /// Keeps the items flagged in `keep` (in order).
  void filter(const std::vector<char>& keep);
};

/// One Fast-Caratheodory level: K contiguous clusters of items, a Caratheodory set of their
/// means (no fewer than min_rows rows survive), kept clusters' items rescaled.
void reduce_level(Items& items, int clusters, long min_rows);

/// Caratheodory directly on the items' means (for at most K items).
void reduce_final(Items& items, long min_rows);

}  // namespace carat::internal
