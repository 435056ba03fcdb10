#include <cmath>
#include <optional>
#include <utility>

#include "factorization_reuse.hpp"
#include "hessian_damping.hpp"
#include "solver_run.hpp"
#include "step_quality.hpp"

namespace carat::internal {

/// Levenberg-Marquardt: each iteration damps H by the trust region, solves, and takes the step
/// if the trust region accepts its gain ratio; a rejected step shrinks the region and the next
/// iteration refactorizes at the same iterate (no relinearization).
void Solver::run_levenberg_marquardt() {
  internal::TrustRegionStrategy region(options_);
  bool reuse_next = false;  // try the next step with the current factorization
  bool probe_next = false;  // ... as a probe for convergence (should_probe_convergence)
  for (int iteration = 1;; ++iteration) {
    IterationSummary row;
    if (!begin_iteration(iteration, &row)) return;
    const Stopwatch iteration_time;

    if (reuse_next) {
      reuse_next = false;
      row.trust_region_radius = region.radius();
      bool stop = false;
      if (try_reused_factorization(row, iteration, iteration_time, probe_next, &stop)) {
        if (stop) return;
        reuse_next = true;
        continue;
      }
    }

    region.damping(system_->diagonal(), &damping_);
    if (bounds_) bounds_->hold_active(buffers_[current_].data(), gradient_, &damping_);
    if (!factorize()) {
      row.linear_solver_failed = true;
      ++summary_.num_linear_solver_failures;
      if (reject_step(row, region, internal::RadiusShrinkCause::kSystemNotPositiveDefinite,
                      iteration_time)) {
        return;
      }
      continue;
    }
    if (!solve_for_step(row, iteration_time)) return;
    if (stop_on_small_step(row, region.radius(), iteration_time)) return;

    double new_cost = trial_cost();
    internal::StepQuality step = internal::judge_step(cost_, new_cost, predicted_decrease());
    row.relative_decrease = step.measured_ratio;
    if (!region.accepts(step)) {
      enter_or_leave_tail(false, step);
      if (reject_step(row, region, internal::RadiusShrinkCause::kStepRejected, iteration_time)) {
        return;
      }
      continue;
    }
    // In an accelerated tail, Anderson's combination of recent steps replaces the solved step
    // when it lowers the cost more; the trust region judges the solved step.
    row.accelerated = accelerate(&new_cost, &step);
    if (row.accelerated) ++summary_.num_accelerated_steps;
    enter_or_leave_tail(true, step);
    ++summary_.num_successful_steps;
    row.step_is_successful = true;
    row.cost_change = step.cost_decrease;
    row.cost = new_cost;
    region.on_accepted(step.gain_ratio);
    row.trust_region_radius = region.radius();
    // A gain ratio well above 1 (the cost fell faster than the model said, as in a slow,
    // linearly converging tail): the exact H buys little over this one, so the next step
    // first tries this factorization.
    // A step the model predicted well that changed the cost by at most sqrt(function_tolerance):
    // the next one, solved with this factorization, probably confirms convergence.
    // In an accelerated tail every next step tries this factorization first.
    const bool slow_tail = internal::should_try_reuse(step, options_) ||
                           (accelerated_tail_ && options_.reuse_factorization);
    probe_next = !slow_tail && internal::should_probe_convergence(step, cost_, options_);
    reuse_next = slow_tail || probe_next;
    if (take_step(row, new_cost, iteration, iteration_time)) return;
  }
}

/// Gauss-Newton: undamped steps (damped only as far as an indefinite system needs), each taken
/// if it does not raise the cost; a step that does ends the solve. The table shows the initial
/// trust region radius, which Gauss-Newton never changes.
void Solver::run_gauss_newton() {
  const double radius = options_.initial_trust_region_radius;
  for (int iteration = 1;; ++iteration) {
    IterationSummary row;
    if (!begin_iteration(iteration, &row)) return;
    const Stopwatch iteration_time;

    if (!factorize_gauss_newton(&row)) {
      ++summary_.num_unsuccessful_steps;
      record(row, iteration_time);
      finish(TerminationType::kFailure,
             "Gauss-Newton: the system is not positive definite even with damping (gauge not fixed "
             "or rank-deficient H?)");
      return;
    }
    if (!solve_for_step(row, iteration_time)) return;
    if (stop_on_small_step(row, radius, iteration_time)) return;

    const double new_cost = trial_cost();
    const internal::StepQuality step = internal::judge_step(cost_, new_cost, predicted_decrease());
    row.relative_decrease = step.measured_ratio;
    if (auto stop = internal::check_gauss_newton_decrease(cost_, new_cost)) {
      ++summary_.num_unsuccessful_steps;
      record(row, iteration_time);
      finish(std::move(*stop));
      return;
    }
    ++summary_.num_successful_steps;
    row.step_is_successful = true;
    row.cost_change = step.cost_decrease;
    row.cost = new_cost;
    row.trust_region_radius = radius;
    if (take_step(row, new_cost, iteration, iteration_time)) return;
  }
}

}  // namespace carat::internal
