#pragma once

// Internal: the Fast-Caratheodory level loop over "items". An item stands for `count` rows that
// share one weight per row; `sums` holds each item's unweighted sum of lifted rows, item-major
// (the L coordinates of item i at sums[i * L]) so that a level's cluster sums and the filtering
// of survivors run over contiguous memory. Items of single rows may instead hold the packed row
// x = [a, e, 0, ...] (packed_cols = r + 1 > 0): a level lifts it on the fly, which reads and
// moves 8 or 16 doubles per row instead of L.

#include <Eigen/Core>
#include <vector>

#include "simd.hpp"

namespace carat::internal {

/// Items of a reduction: their lifted sums, row counts and per-row weights. Storage only grows
/// (reuse one Items across calls to avoid page faults on fresh memory).
struct Items {
  AlignedDoubles sums;         ///< L per item, item-major; items [0, size()) are live
  std::vector<long> counts;    ///< rows per item
  std::vector<double> weight;  ///< weight of each row of the item
  std::vector<int> ids;        ///< caller's id of each item
  Eigen::Index dim = 0;        ///< doubles per item: L, or the packed row's stride
  Eigen::Index lifted = 0;     ///< L, the lifted dimension
  int packed_cols = 0;         ///< r + 1 when items are packed rows (count 1 each), else 0

  /// Makes room for `count` items of lifted sums in dimension L (contents unspecified).
  void reset(Eigen::Index L, int count);
  /// Makes room for `count` packed rows of r columns (contents unspecified).
  void reset_packed(int r, int count);
  /// Number of items.
  int size() const { return static_cast<int>(counts.size()); }
  /// Rows represented by all items.
  long rows() const;
  /// The L coordinates of item i.
  double* item(Eigen::Index i) { return sums.data() + i * dim; }
  /// The L coordinates of item i.
  const double* item(Eigen::Index i) const { return sums.data() + i * dim; }
  /// Keeps the items flagged in `keep` (in order).
  void filter(const std::vector<char>& keep);
  /// Keeps the first `count` items.
  void truncate(int count);
  /// Moves items [from, size()) to `tail` (replacing its contents).
  void split_tail(int from, Items& tail);
  /// Appends the items of `tail`.
  void append(const Items& tail);
};

/// One Fast-Caratheodory level: K contiguous clusters of items, a Caratheodory set of their
/// means (no fewer than min_rows rows survive), kept clusters' items rescaled.
void reduce_level(Items& items, int clusters, long min_rows);

/// Caratheodory directly on the items' means (for at most K items).
void reduce_final(Items& items, long min_rows);

}  // namespace carat::internal
