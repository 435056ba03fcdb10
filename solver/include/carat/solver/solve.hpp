#pragma once

/// Entry point of the nonlinear least-squares solver.

#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat {

/// Minimizes problem's cost 1/2 sum rho(|r|^2) starting at its current values and writes the
/// best iterate back into it (never a non-finite value). Does not throw for numerical trouble
/// or bad settings: an indefinite or singular system raises the damping, and invalid options,
/// non-finite costs or unusable steps end the solve with a reason in the summary. The iterate
/// accepted in the last of max_iterations is returned without being relinearized (so its
/// gradient is not tested): a one-iteration solve costs one linearization.
///
/// LM details beyond Ceres's trust region: after an accepted step whose gain ratio exceeds
/// options.factor_reuse_ratio (the cost fell faster than the model predicted, as in a slow,
/// linearly converging tail), the next step is first tried with the previous numeric
/// factorization (a triangular solve instead of a factorization) and kept only if its gain
/// ratio against the current model exceeds 1/2 and it lowers the cost by at least half as much
/// as the last freshly factorized step did; otherwise H is factorized afresh. Such a step also
/// starts an accelerated tail (options.anderson_memory > 0, no bounds), which lasts until a step
/// is rejected: each accepted step is compared with Anderson's combination of the last
/// anderson_memory steps (one more cost evaluation) and replaced by it if its cost is lower,
/// every next step first tries the previous factorization, and a reused step is kept while it
/// lowers the cost by more than function_tolerance * cost. Steps whose
/// predicted decrease is below the rounding of the cost are taken unless the cost rose by more
/// than that rounding.
SolverSummary solve(const SolverOptions& options, Problem& problem);

}  // namespace carat
