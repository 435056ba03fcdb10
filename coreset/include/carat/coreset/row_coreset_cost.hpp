#pragma once

/// What select_coreset_rows() will take before it runs, so that a caller can refuse a size the
/// machine cannot hold or a call that would run for many minutes (carat coreset-check and the
/// Python module's carat.coreset check it against the machine).

#include "carat/coreset/row_coreset.hpp"

namespace carat {

/// The estimated cost of one select_coreset_rows() call.
struct RowCoresetCost {
  int lifted_dim = 0;       ///< L = r(r+1)/2 + r + 1, doubles per lifted row
  int clusters = 0;         ///< K clusters per level (the options' or the default)
  long lifted_rows = 0;     ///< rows held lifted (or packed) at once after the chunk phase
  double levels = 0.0;      ///< Fast-Caratheodory levels, ln(N / M) / ln(K / (L + 1)), >= 1
  double bytes = 0.0;       ///< peak scratch, bytes: chunk sums, the lifted rows, and the
                            ///< eliminations' tableaus (L x K each); the input J and e not counted
  double operations = 0.0;  ///< floating-point operations, roughly: levels x K L^2 + 4 N L
};

/// The cost of selecting the coreset of `rows` rows of `reduced_dim` columns under `options`
/// (nothing is allocated). Throws carat::Error for a negative size or target.
RowCoresetCost estimate_row_coreset(long rows, int reduced_dim,
                                    const RowCoresetOptions& options = {});

}  // namespace carat
