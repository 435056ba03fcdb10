#include "factorization_reuse.hpp"

#include <cmath>

namespace carat::internal {

bool is_slow_tail_step(const StepQuality& accepted_step, const SolverOptions& options) {
  return accepted_step.gain_ratio > options.factor_reuse_ratio &&
         accepted_step.model_decrease > 1e3 * accepted_step.rounding;
}

bool should_try_reuse(const StepQuality& accepted_step, const SolverOptions& options) {
  return options.reuse_factorization && is_slow_tail_step(accepted_step, options);
}

bool should_probe_convergence(const StepQuality& accepted_step, double cost,
                              const SolverOptions& options) {
  return options.reuse_factorization && std::abs(accepted_step.gain_ratio - 1.0) <= 0.1 &&
         accepted_step.cost_decrease <= std::sqrt(options.function_tolerance) * cost;
}

bool probe_converged(const StepQuality& step, double cost, double function_tolerance) {
  // Each test is false for a NaN cost.
  return step.cost_is_finite && step.cost_decrease >= 0.0 &&
         step.cost_decrease <= function_tolerance * cost &&
         (step.measured_ratio > 0.5 || step.below_rounding);
}

bool keeps_reused_step(const StepQuality& step, double fresh_decrease, double cost,
                       double function_tolerance) {
  // Each test is false for a NaN cost.
  return step.measured_ratio > 0.5 && step.cost_decrease >= 0.5 * fresh_decrease &&
         step.cost_decrease > function_tolerance * cost;
}

bool keeps_accelerated_tail_step(const StepQuality& step, double fresh_decrease, double cost,
                                 double function_tolerance) {
  // Each test is false for a NaN cost.
  return (step.cost_is_finite && step.cost_decrease > function_tolerance * cost &&
          step.cost_decrease >= 0.1 * fresh_decrease) ||
         probe_converged(step, cost, function_tolerance);
}

}  // namespace carat::internal
