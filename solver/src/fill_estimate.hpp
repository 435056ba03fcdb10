#pragma once

// Internal: what a sparse Cholesky factorization of a block-structured symmetric matrix would
// hold, found before anything of its size is allocated: an AMD ordering of the block graph, its
// elimination tree, and every block of the factor counted once (the row subtrees of the tree),
// each weighed by the tangent sizes of its two variables. make_linear_system() compares the whole
// system with the Schur complement's reduced system by it.

#include <cstddef>
#include <vector>

namespace carat::internal {

/// A symmetric block pattern: node k has `dims[k]` scalar rows; `neighbours[k]` lists the other
/// nodes it shares an off-diagonal block with (both directions present, no duplicates needed).
struct BlockGraph {
  std::vector<int> dims;                     ///< scalar size of each node
  std::vector<std::vector<int>> neighbours;  ///< adjacency (symmetric)
};

/// Scalar entries of the lower triangle of the matrix and of its Cholesky factor.
struct FillEstimate {
  double matrix_entries = 0.0;  ///< lower triangle with the diagonal
  double factor_entries = 0.0;  ///< the factor L under AMD (exact for that ordering)
};

/// Counts the lower triangle of `graph` and of its factor under CHOLMOD's AMD ordering. Stops
/// counting the factor once it exceeds `stop_after` entries (the result then is at least that).
/// Throws carat::Error if CHOLMOD's ordering fails.
FillEstimate estimate_fill(const BlockGraph& graph, double stop_after);

}  // namespace carat::internal
