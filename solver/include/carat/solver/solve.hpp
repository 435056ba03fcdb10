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
SolverSummary solve(const SolverOptions& options, Problem& problem);

}  // namespace carat
