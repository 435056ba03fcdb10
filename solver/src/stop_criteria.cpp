#include "stop_criteria.hpp"

#include <cmath>

#include "carat/base/error.hpp"

namespace carat::internal {
std::optional<StopReason> check_gradient_tolerance(double gradient_max_norm,
                                                   double gradient_tolerance) {
  if (!(gradient_max_norm <= gradient_tolerance)) return std::nullopt;
  return StopReason{TerminationType::kConvergence, "gradient tolerance reached: max |gradient| = " +
                                                       message_number(gradient_max_norm)};
}

std::optional<StopReason> check_iteration_limit(int completed_iterations, int max_iterations) {
  if (completed_iterations < max_iterations) return std::nullopt;
  return StopReason{TerminationType::kNoConvergence, "maximum number of iterations reached (" +
                                                         std::to_string(max_iterations) + ")"};
}

std::optional<StopReason> check_parameter_tolerance(double step_norm, double parameter_norm,
                                                    double parameter_tolerance) {
  if (!(step_norm <= parameter_tolerance * (parameter_norm + parameter_tolerance))) {
    return std::nullopt;
  }
  return StopReason{TerminationType::kConvergence,
                    "parameter tolerance reached: |step| = " + message_number(step_norm)};
}

std::optional<StopReason> check_function_tolerance(double cost_decrease, double previous_cost,
                                                   double function_tolerance) {
  if (!(std::abs(cost_decrease) <= function_tolerance * previous_cost)) return std::nullopt;
  const double relative = previous_cost > 0.0 ? std::abs(cost_decrease) / previous_cost : 0.0;
  return StopReason{
      TerminationType::kConvergence,
      "function tolerance reached: |cost change| / cost = " + message_number(relative)};
}

std::optional<StopReason> check_trust_region_radius(double radius, double min_radius,
                                                    RadiusShrinkCause cause) {
  if (!(radius < min_radius)) return std::nullopt;
  std::string message = "trust region radius below min_trust_region_radius";
  if (cause == RadiusShrinkCause::kSystemNotPositiveDefinite) {
    message += " (system not positive definite)";
  }
  return StopReason{TerminationType::kNoConvergence, std::move(message)};
}

std::optional<StopReason> check_gauss_newton_decrease(double cost, double trial_cost) {
  if (std::isfinite(trial_cost) && trial_cost <= cost) return std::nullopt;
  return StopReason{TerminationType::kNoConvergence,
                    std::isfinite(trial_cost) ? "Gauss-Newton step did not decrease the cost"
                                              : "Gauss-Newton step gave a non-finite cost"};
}

}  // namespace carat::internal
