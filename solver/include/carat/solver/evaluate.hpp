#pragma once

/// The cost and gradient of a whole problem at its current values, without a solve: what a
/// caller needs to judge a point found some other way (e.g. by solving a compressed copy of the
/// problem, whose own summary reports the compressed cost).

#include <Eigen/Core>

#include "carat/solver/problem.hpp"

namespace carat {

/// A problem's cost and gradient at its current values.
struct ProblemEvaluation {
  double cost = 0.0;               ///< 1/2 sum_blocks rho(|r|^2), as solve() reports it
  Eigen::VectorXd gradient;        ///< over the free variables' tangents, in variable order
  double gradient_max_norm = 0.0;  ///< max |gradient| (0 with no free variable)
  bool finite = true;              ///< cost and gradient are finite
};

/// Evaluates every block once (its accumulate(), in parallel with `num_threads`; the result does
/// not depend on the thread count), then a block source's blocks (their linearization records).
/// Constant variables contribute no gradient entries.
ProblemEvaluation evaluate_problem(const Problem& problem, int num_threads = 1);

/// The cost 1/2 sum_blocks rho(|r|^2) alone: residuals only (each block's squared_norm(), in
/// parallel with `num_threads`, summed in block order), several times cheaper than
/// evaluate_problem() for blocks whose Jacobians cost more than their residuals; a block
/// source's costs are added after the own blocks'.
double evaluate_cost(const Problem& problem, int num_threads = 1);

}  // namespace carat
