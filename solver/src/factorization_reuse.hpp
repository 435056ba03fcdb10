#pragma once

// Internal: Levenberg-Marquardt steps solved with the numeric factorization of an earlier
// iterate. In a slow, linearly converging tail the cost falls faster than the model predicts
// (gain ratios well above 1), so a recent H serves about as well as the exact one, and a
// triangular solve costs far less than a factorization.

#include "carat/solver/solver_options.hpp"
#include "step_quality.hpp"

namespace carat::internal {

/// True if `accepted_step` marks a slow tail: its gain ratio exceeds factor_reuse_ratio and its
/// predicted decrease is above 1000 times the cost's rounding (the ratio is measured, not noise).
bool is_slow_tail_step(const StepQuality& accepted_step, const SolverOptions& options);
/// True if the step after `accepted_step` first tries the same factorization: reuse is on and
/// is_slow_tail_step().
bool should_try_reuse(const StepQuality& accepted_step, const SolverOptions& options);

/// True if the step after `accepted_step` (taken from an iterate of cost `cost`) probes for
/// convergence with the same factorization: reuse is on, the gain ratio is within 0.1 of 1 (the
/// quadratic model held, so H changes little) and the step lowered the cost by at most
/// sqrt(function_tolerance) * `cost` (converging quadratically, the next step would lower it by
/// about function_tolerance * cost: it only confirms convergence, and a triangular solve on this
/// factorization confirms it as well as a fresh one, to a cost that differs in the 10th digit).
bool should_probe_convergence(const StepQuality& accepted_step, double cost,
                              const SolverOptions& options);

/// True if a convergence probe (see should_probe_convergence) ends the solve: its step lowers
/// the cost by no more than function_tolerance * `cost` and not by less than 0, and its ratio
/// against the current undamped model exceeds 1/2 unless the decrease is within rounding.
bool probe_converged(const StepQuality& step, double cost, double function_tolerance);

/// True if a step solved with an earlier factorization is kept: its ratio against the current
/// undamped model exceeds 1/2, it lowers the cost by at least half of `fresh_decrease` (the
/// decrease of the last step from a fresh factorization) and by more than function_tolerance *
/// `cost`. A NaN or +inf trial cost fails these tests.
bool keeps_reused_step(const StepQuality& step, double fresh_decrease, double cost,
                       double function_tolerance);
/// The rule of an accelerated tail (SolverOptions::anderson_memory), where Anderson's method
/// makes up for an older factorization: a reused step is kept if it lowers the cost by more
/// than function_tolerance * `cost` and by at least a tenth of `fresh_decrease`, or if
/// probe_converged() says it ends the solve. A NaN or +inf trial cost fails.
bool keeps_accelerated_tail_step(const StepQuality& step, double fresh_decrease, double cost,
                                 double function_tolerance);

}  // namespace carat::internal
