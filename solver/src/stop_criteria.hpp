#pragma once

// Internal: the tests that end a solve. Each returns the reason to stop, or nothing when the
// solve goes on; the caller decides when in an iteration each one applies.

#include <optional>
#include <string>

#include "carat/solver/solver_summary.hpp"

namespace carat::internal {

/// Why a solve ends: the termination type and the summary's message.
struct StopReason {
  TerminationType type = TerminationType::kFailure;  ///< what the summary reports
  std::string message;                               ///< human-readable reason
};

/// Why the trust region was shrunk before its radius was tested.
enum class RadiusShrinkCause {
  kStepRejected,               ///< the step's gain ratio (or trial cost) did not qualify
  kSystemNotPositiveDefinite,  ///< the damped system could not be factorized
};

/// Converged when max |gradient| <= gradient_tolerance (gradient in cost units per tangent unit).
std::optional<StopReason> check_gradient_tolerance(double gradient_max_norm,
                                                   double gradient_tolerance);

/// Out of iterations once completed_iterations >= max_iterations (no convergence).
std::optional<StopReason> check_iteration_limit(int completed_iterations, int max_iterations);

/// Converged when |step| <= parameter_tolerance * (|x| + parameter_tolerance), with |x| the
/// norm of the free variables' values and |step| the norm of the tangent step.
std::optional<StopReason> check_parameter_tolerance(double step_norm, double parameter_norm,
                                                    double parameter_tolerance);

/// Converged when |cost_decrease| <= function_tolerance * previous_cost (cost units).
std::optional<StopReason> check_function_tolerance(double cost_decrease, double previous_cost,
                                                   double function_tolerance);

/// No convergence when the radius has fallen below min_radius (strictly); the message names
/// an indefinite system when that is why the radius shrank.
std::optional<StopReason> check_trust_region_radius(double radius, double min_radius,
                                                    RadiusShrinkCause cause);

/// Gauss-Newton has no fallback for a step that does not lower the cost: no convergence when
/// trial_cost is not finite or above cost.
std::optional<StopReason> check_gauss_newton_decrease(double cost, double trial_cost);

}  // namespace carat::internal
