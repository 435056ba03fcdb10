#pragma once

// Internal: evaluates every residual block of a Problem, in parallel and deterministically,
// at one of two value buffers (the current iterate and a trial point).

#include <Eigen/Core>
#include <atomic>
#include <cstddef>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "block_linearizations.hpp"
#include "carat/solver/problem.hpp"

namespace carat::internal {

/// Per-thread scratch of evaluate_block().
struct BlockScratch {
  Eigen::MatrixXd H_r;  ///< the block's reduced H, then its full H
  Eigen::MatrixXd H;    ///< scratch for the lift of a reduced block
  Eigen::VectorXd b_r;  ///< the block's reduced b
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> A;  ///< reduced map
};

/// Lowers first_bad to i if i is smaller (thread-safe): the lowest bad block wins.
void record_bad_block(std::atomic<std::size_t>& first_bad, std::size_t i);

class BlockEvaluator {
 public:
  explicit BlockEvaluator(const Problem& problem);

  /// Points buffer `which` (0 or 1) at `values` (a copy of the problem's all_values()).
  void bind(int which, const double* values);

  /// The values buffer `which` points at (all_values() layout).
  std::span<const double> values(int which) const {
    return {values_[which], problem_.all_values().size()};
  }

  /// The problem evaluated.
  const Problem& problem() const { return problem_; }

  /// Linearizes every block at buffer `which` into `out` (H, b lifted to the full tangent
  /// space, robust loss applied). Returns false and names the block in *error if a value is
  /// not finite.
  bool linearize(int which, BlockLinearizations* out, std::string* error) const;
  /// As linearize(), for blocks [first, last) only: block i's H and b at its offsets less block
  /// first's in `out` (storage allocated for runs of at least last - first blocks), its cost at
  /// out->cost[i]. The error names the lowest bad block of the run.
  bool linearize_run(int which, std::size_t first, std::size_t last, BlockLinearizations* out,
                     std::string* error) const;

  /// Linearizes block i at buffer `which`: its H lifted to the full tangent space with the loss
  /// applied, as a lower triangle packed by columns into packed_h (D (D + 1) / 2), b into b (D)
  /// and 1/2 rho into *cost. False if any of them is not finite.
  bool evaluate_block(std::size_t i, int which, BlockScratch& scratch, double* packed_h, double* b,
                      double* cost) const;

  /// Evaluates all n rows of block i at buffer `which` (no loss, not reduced): the Jacobian rows
  /// (n x D, row-major) then the n residuals into `out`, and 1/2 |r|^2 into *cost. False if
  /// something is not finite.
  bool evaluate_rows(std::size_t i, int which, int n, double* out, double* cost) const;

  /// "residual block i ('name'): <which row is not finite, or what it threw>" at `which`.
  std::string describe_bad_block(std::size_t i, int which) const;

  /// Cost 1/2 sum rho at buffer `which` (per-block parallel, summed in block order; a block
  /// source's costs after the own blocks').
  double cost(int which) const;

  /// The own blocks' costs 1/2 rho at buffer `which` (per-block parallel), in block order.
  const std::vector<double>& own_costs(int which) const;

  /// Allocates the per-block storage of `out` for this problem: offsets and costs for every
  /// block, H and b for the largest run of `run_blocks` consecutive blocks from a multiple of
  /// run_blocks (every block by default).
  void allocate(BlockLinearizations* out,
                std::size_t run_blocks = std::numeric_limits<std::size_t>::max()) const;

 private:
  bool evaluate_block_unguarded(std::size_t i, int which, BlockScratch& scratch, double* packed_h,
                                double* b, double* cost) const;

  const Problem& problem_;
  std::vector<int> dims_;                   // D per block
  std::vector<std::size_t> param_begin_;    // per block, into param_offsets_
  std::vector<std::size_t> param_offsets_;  // value offsets of each block's variables
  std::vector<const double*> pointers_[2];  // resolved pointers per buffer
  const double* values_[2] = {nullptr, nullptr};
  mutable std::vector<double> block_cost_;
};

}  // namespace carat::internal
