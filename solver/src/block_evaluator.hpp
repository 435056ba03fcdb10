#pragma once

// Internal: evaluates every residual block of a Problem, in parallel and deterministically,
// at one of two value buffers (the current iterate and a trial point).

#include <cstddef>
#include <string>
#include <vector>

#include "carat/solver/problem.hpp"
#include "sparse_system.hpp"

namespace carat::internal {

class BlockEvaluator {
 public:
  explicit BlockEvaluator(const Problem& problem);

  /// Points buffer `which` (0 or 1) at `values` (a copy of the problem's all_values()).
  void bind(int which, const double* values);

  /// Linearizes every block at buffer `which` into `out` (H, b lifted to the full tangent
  /// space, robust loss applied). Returns false and names the block in *error if a value is
  /// not finite.
  bool linearize(int which, BlockLinearizations* out, std::string* error) const;

  /// Cost 1/2 sum rho at buffer `which` (per-block parallel, summed in block order).
  double cost(int which) const;

  /// Allocates the per-block storage of `out` for this problem.
  void allocate(BlockLinearizations* out) const;

 private:
  const Problem& problem_;
  std::vector<std::size_t> param_begin_;    // per block, into param_offsets_
  std::vector<std::size_t> param_offsets_;  // value offsets of each block's variables
  std::vector<const double*> pointers_[2];  // resolved pointers per buffer
  mutable std::vector<double> block_cost_;
};

}  // namespace carat::internal
