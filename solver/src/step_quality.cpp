#include "step_quality.hpp"

#include <cmath>
#include <limits>

namespace carat::internal {

double model_decrease(const Eigen::VectorXd& gradient, const Eigen::VectorXd& delta,
                      const Eigen::VectorXd& h_delta) {
  return -gradient.dot(delta) - 0.5 * delta.dot(h_delta);
}

double damped_model_decrease(const Eigen::VectorXd& gradient, const Eigen::VectorXd& delta,
                             const Eigen::VectorXd& damping) {
  return 0.5 * (-gradient.dot(delta) + delta.dot(damping.cwiseProduct(delta)));
}

double cost_rounding(double cost) {
  return 64.0 * std::numeric_limits<double>::epsilon() * std::abs(cost);
}

StepQuality judge_step(double cost, double trial_cost, double model_decrease) {
  StepQuality step;
  step.model_decrease = model_decrease;
  step.cost_decrease = cost - trial_cost;
  step.rounding = cost_rounding(cost);
  step.cost_is_finite = std::isfinite(trial_cost);
  step.measured_ratio = model_decrease > 0.0 ? step.cost_decrease / model_decrease : -1.0;
  step.below_rounding = model_decrease > 0.0 && model_decrease <= step.rounding &&
                        step.cost_is_finite && step.cost_decrease >= -step.rounding;
  step.gain_ratio = step.below_rounding ? 1.0 : step.measured_ratio;
  return step;
}

}  // namespace carat::internal
