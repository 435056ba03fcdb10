#pragma once

/// A conformance check of the residual block contract (residual_block.hpp) for any block, a
/// user's plugin as much as carat's own (Ceres's gradient checker and manifold test utilities are
/// the model). It evaluates the block at given values and checks:
/// - tangent_dims(): the same span (pointer and values) on every call, sizes matching the
///   manifolds, at least one row;
/// - evaluate_rows() honours `rows`: asked for one row it writes one residual and one Jacobian
///   row, nothing beyond (a plugin that writes all N rows overflows the caller's buffer);
/// - the Jacobian J = J_r A against central differences through the manifolds' plus();
/// - any subset of rows, in any order with repeats, equals the same rows of a full evaluation;
/// - accumulate() and squared_norm() equal the defaults built on evaluate_rows();
/// - extract_rows() and extract_weighted_rows(), when offered, hold exactly the selected rows
///   (times sqrt(w) for the weighted extract), with the same tangent_dims() and reduced_dim().

#include <span>
#include <string>
#include <vector>

#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// Tolerances of check_residual_block().
struct BlockCheckOptions {
  JacobianCheckOptions jacobian;      ///< step and tolerances of the numeric Jacobian check
  double relative_tolerance = 1e-10;  ///< subsets, accumulate, squared_norm, extracts (relative)
  int subset_rows = 64;               ///< rows drawn (with repeats) for the subset check
  unsigned seed = 1;                  ///< seed of the subsets and weights drawn
};

/// What check_residual_block() found.
struct BlockCheckReport {
  bool ok = false;                    ///< every check passed
  std::vector<std::string> failures;  ///< one line per failed check
  JacobianCheckResult jacobian;       ///< the Jacobian comparison
  /// "ok", or the failures joined by "; ".
  std::string summary() const;
};

/// What check_problem() found.
struct ProblemCheckReport {
  bool ok = true;                     ///< every block checked passed
  int checked_blocks = 0;             ///< blocks checked: the first of each distinct type
  std::vector<std::string> failures;  ///< one paragraph per failing block, naming it
  /// "ok (N block types checked)", or the failures joined by newlines.
  std::string summary() const;
};

/// Checks `block` at `params` (one pointer per variable) with `manifolds` (one per variable, in
/// the block's order). Never throws for a misbehaving block: what it throws becomes a failure.
/// Throws carat::Error only when the counts of manifolds and parameters differ from the block's.
BlockCheckReport check_residual_block(const ResidualBlock& block,
                                      std::span<const Manifold* const> manifolds,
                                      ParameterPointers params,
                                      const BlockCheckOptions& options = {});

/// Runs check_residual_block() on the first block of every distinct type (C++ dynamic type) in
/// `problem`, at the problem's current values and with its manifolds: the conformance check of
/// every kind of block a solve will evaluate, in one call (SolverOptions::check_blocks runs it
/// before the first iteration). Never throws for a misbehaving block.
ProblemCheckReport check_problem(const Problem& problem, const BlockCheckOptions& options = {});

}  // namespace carat
