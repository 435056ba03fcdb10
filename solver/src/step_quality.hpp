#pragma once

// Internal: how a trial step fared against the quadratic model that produced it. Costs are
// 1/2 sum rho (as in SolverSummary); the model at the current iterate is
// m(delta) = cost + gradient.delta + 1/2 delta.H.delta.

#include <Eigen/Core>

namespace carat::internal {

/// Decrease of the undamped model for a step `delta`, given h_delta = H delta:
/// -gradient.delta - 1/2 delta.h_delta, in cost units.
double model_decrease(const Eigen::VectorXd& gradient, const Eigen::VectorXd& delta,
                      const Eigen::VectorXd& h_delta);

/// Decrease of the undamped model for a step solved from (H + diag(damping)) delta = -gradient:
/// 1/2 (-gradient.delta + delta.diag(damping).delta), in cost units (no product with H needed).
double damped_model_decrease(const Eigen::VectorXd& gradient, const Eigen::VectorXd& delta,
                             const Eigen::VectorXd& damping);

/// An upper bound on the rounding error of a cost near `cost` (a sum of many terms), in cost
/// units: 64 eps |cost|. Cost changes below it are not measurable.
double cost_rounding(double cost);

/// A trial step judged against its model.
struct StepQuality {
  double cost_decrease = 0.0;   ///< cost - trial cost, in cost units (negative: the cost rose)
  double model_decrease = 0.0;  ///< decrease the model predicted, in cost units
  double rounding = 0.0;        ///< cost_rounding() of the cost the step started from
  /// cost_decrease / model_decrease; -1 when the model predicts no decrease (the table shows it)
  double measured_ratio = -1.0;
  double gain_ratio = -1.0;  ///< ratio the decisions use: measured_ratio, or 1 if below_rounding
  bool below_rounding =
      false;  ///< predicted decrease within the rounding, cost not risen beyond it
  bool cost_is_finite = false;  ///< the trial cost is finite
};

/// Judges a step from `cost` to `trial_cost` whose model predicted `model_decrease`. A predicted
/// decrease in (0, rounding] cannot be checked against the cost: such a step counts as gain
/// ratio 1 when the trial cost is finite and not above cost + rounding.
StepQuality judge_step(double cost, double trial_cost, double model_decrease);

}  // namespace carat::internal
