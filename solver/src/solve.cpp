#include "carat/solver/solve.hpp"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "block_evaluator.hpp"
#include "carat/solver/error.hpp"
#include "carat/solver/stopwatch.hpp"
#include "sparse_system.hpp"

namespace carat {
namespace {

/// Applies the tangent step to every free variable: out = x [+] delta.
void apply_step(const Problem& problem, const std::vector<int>& var_offset, const double* x,
                const Eigen::VectorXd& delta, double* out) {
  const int n = problem.num_variables();
  for (int v = 0; v < n; ++v) {
    const VariableId id{v};
    const std::size_t offset = problem.value_offset(id);
    const Manifold& m = problem.manifold(id);
    const int t = var_offset[static_cast<std::size_t>(v)];
    if (t < 0) {
      std::copy_n(x + offset, m.ambient_size(), out + offset);
    } else {
      m.plus(x + offset, delta.data() + t, out + offset);
    }
  }
}

double free_parameter_norm(const Problem& problem, const std::vector<int>& var_offset,
                           const double* x) {
  double sum = 0.0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    if (var_offset[static_cast<std::size_t>(v)] < 0) continue;
    const VariableId id{v};
    const double* p = x + problem.value_offset(id);
    for (int k = 0; k < problem.manifold(id).ambient_size(); ++k) sum += p[k] * p[k];
  }
  return std::sqrt(sum);
}

/// An upper bound on the rounding error of a cost near `cost` (a sum of many terms): cost
/// changes below it are not measurable.
double cost_rounding(double cost) {
  return 64.0 * std::numeric_limits<double>::epsilon() * std::abs(cost);
}

/// A number as %g writes it (std::to_string prints 1e-12 as "0.000000").
std::string number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

/// The termination message when max_iterations ends the solve.
std::string iteration_limit_message(const SolverOptions& options) {
  return "maximum number of iterations reached (" + std::to_string(options.max_iterations) + ")";
}

class Solver {
 public:
  Solver(const SolverOptions& options, Problem& problem, SolverSummary& summary)
      : options_(options), problem_(problem), summary_(summary) {}

  void run();
  /// Copies the last accepted iterate (finite cost, lowest so far) into the problem.
  void write_back() {
    if (!buffers_[current_].empty()) problem_.set_all_values(buffers_[current_]);
  }

 private:
  bool linearize();
  bool take_step(IterationSummary& row, double new_cost, int iteration,
                 const Stopwatch& iteration_time);
  bool try_reused_factorization(IterationSummary& row, int iteration,
                                const Stopwatch& iteration_time, bool* stop);
  void record(IterationSummary row, const Stopwatch& iteration_time);
  bool finish(TerminationType type, std::string message);

  const SolverOptions& options_;
  Problem& problem_;
  SolverSummary& summary_;
  Stopwatch solve_time_;  ///< since the solver was made
  std::unique_ptr<internal::SparseSystem> system_;
  std::unique_ptr<internal::BlockEvaluator> evaluator_;
  internal::BlockLinearizations lin_;
  std::vector<double> buffers_[2];
  int current_ = 0;
  double cost_ = 0.0;
  double fresh_decrease_ = 0.0;  ///< cost decrease of the last step from a fresh factorization
  Eigen::VectorXd gradient_;
  Eigen::VectorXd delta_;    ///< scratch: the step
  Eigen::VectorXd rhs_;      ///< scratch: -gradient
  Eigen::VectorXd h_delta_;  ///< scratch: H delta
};

bool Solver::finish(TerminationType type, std::string message) {
  summary_.termination = type;
  summary_.message = std::move(message);
  return true;
}

void Solver::record(IterationSummary row, const Stopwatch& iteration_time) {
  row.iteration_time_s = iteration_time.elapsed_s();
  row.cumulative_time_s = solve_time_.elapsed_s();
  if (options_.record_iterations) summary_.iterations.push_back(row);
}

bool Solver::linearize() {
  Stopwatch stage;
  std::string error;
  if (!evaluator_->linearize(current_, &lin_, &error)) {
    summary_.time.linearize_s += stage.elapsed_s();
    return finish(TerminationType::kFailure, error), false;
  }
  summary_.time.linearize_s += stage.restart();
  system_->assemble(lin_, &gradient_);
  summary_.time.assembly_s += stage.elapsed_s();
  cost_ = 0.0;
  for (double c : lin_.cost) cost_ += c;
  return true;
}

/// Moves to the trial iterate (cost new_cost) and relinearizes there, except after the last
/// permitted iteration: nothing would use that H and b (a one-iteration solve, as align() runs
/// per correspondence set, then costs one linearization instead of two), so its gradient is not
/// tested either. Records the row and tests the function tolerance. True: the solve ends.
bool Solver::take_step(IterationSummary& row, double new_cost, int iteration,
                       const Stopwatch& iteration_time) {
  const double old_cost = cost_;
  const double decrease = old_cost - new_cost;
  if (!row.reused_factorization) fresh_decrease_ = decrease;
  current_ = 1 - current_;
  const bool last = iteration >= options_.max_iterations;
  if (last) {
    cost_ = new_cost;
  } else if (!linearize()) {
    record(row, iteration_time);
    return true;
  }
  record(row, iteration_time);
  if (std::abs(decrease) <= options_.function_tolerance * old_cost) {
    finish(TerminationType::kConvergence,
           "function tolerance reached: |cost change| / cost = " +
               number(old_cost > 0.0 ? std::abs(decrease) / old_cost : 0.0));
    return true;
  }
  if (last) {
    finish(TerminationType::kNoConvergence, iteration_limit_message(options_));
    return true;
  }
  return false;
}

/// A step solved with the factorization of an earlier iterate: no numeric factorization, only
/// a triangular solve, H delta for the model at the current iterate, and one cost evaluation.
/// Kept only if its gain ratio against the current (undamped) model exceeds 1/2 and it lowers
/// the cost by more than the function tolerance and by at least half as much as the step of
/// the fresh factorization did: a run of reused steps ends once they fall to half of what a
/// fresh one achieved. Then returns true (*stop: the solve ends); otherwise nothing is
/// recorded and the caller factorizes afresh.
bool Solver::try_reused_factorization(IterationSummary& row, int iteration,
                                      const Stopwatch& iteration_time, bool* stop) {
  const Stopwatch solve_time;
  rhs_ = -gradient_;
  system_->solve(rhs_, &delta_);
  if (delta_.allFinite()) system_->multiply(delta_, &h_delta_);
  summary_.time.solve_s += solve_time.elapsed_s();
  if (!delta_.allFinite()) {
    ++summary_.num_refused_reuses;
    return false;
  }
  const double model_decrease = -gradient_.dot(delta_) - 0.5 * delta_.dot(h_delta_);
  const int trial = 1 - current_;
  apply_step(problem_, system_->variable_offset(), buffers_[current_].data(), delta_,
             buffers_[trial].data());
  const Stopwatch cost_time;
  const double new_cost = evaluator_->cost(trial);
  summary_.time.cost_s += cost_time.elapsed_s();
  const double decrease = cost_ - new_cost;
  const double ratio = model_decrease > 0.0 ? decrease / model_decrease : -1.0;
  // Each test is false for a NaN cost.
  if (!(ratio > 0.5) || !(decrease >= 0.5 * fresh_decrease_) ||
      !(decrease > options_.function_tolerance * cost_)) {
    ++summary_.num_refused_reuses;
    return false;
  }
  ++summary_.num_successful_steps;
  ++summary_.num_reused_factorizations;
  row.step_norm = delta_.norm();
  row.relative_decrease = ratio;
  row.cost_change = decrease;
  row.cost = new_cost;
  row.step_is_successful = true;
  row.reused_factorization = true;
  *stop = take_step(row, new_cost, iteration, iteration_time);
  return true;
}

void Solver::run() {
  summary_.num_threads = options_.num_threads;
  summary_.method =
      options_.method == Method::kLevenbergMarquardt ? "levenberg_marquardt" : "gauss_newton";
  summary_.num_variables = problem_.num_variables();
  summary_.num_residual_blocks = problem_.num_residual_blocks();
  summary_.num_residual_rows = problem_.num_residual_rows();
  summary_.residual_memory_bytes = problem_.residual_memory_bytes();
  for (int v = 0; v < problem_.num_variables(); ++v) {
    if (!problem_.is_constant(VariableId{v})) ++summary_.num_free_variables;
  }

  const Stopwatch symbolic_time;
  system_ = std::make_unique<internal::SparseSystem>(problem_, options_.ordering);
  summary_.time.symbolic_s += symbolic_time.elapsed_s();
  summary_.num_tangent_parameters = system_->size();
  summary_.hessian_nonzeros = system_->hessian_nonzeros();
  summary_.factor_nonzeros = system_->factor_nonzeros();
  summary_.linear_solver = system_->description();

  const auto values = problem_.all_values();
  buffers_[0].assign(values.begin(), values.end());
  buffers_[1] = buffers_[0];
  evaluator_ = std::make_unique<internal::BlockEvaluator>(problem_);
  for (int k = 0; k < 2; ++k) evaluator_->bind(k, buffers_[k].data());
  evaluator_->allocate(&lin_);

  const Stopwatch iteration0_time;
  if (!linearize()) return;
  summary_.initial_cost = cost_;
  summary_.final_cost = cost_;
  if (!std::isfinite(cost_)) {
    finish(TerminationType::kFailure, "the initial cost is not finite");
    return;
  }
  IterationSummary row0;
  row0.cost = cost_;
  row0.gradient_max_norm = gradient_.size() ? gradient_.cwiseAbs().maxCoeff() : 0.0;
  row0.trust_region_radius = options_.initial_trust_region_radius;
  row0.step_is_successful = true;
  record(row0, iteration0_time);

  if (system_->size() == 0) {
    finish(TerminationType::kConvergence, "no free variables: nothing to optimize");
    return;
  }

  const bool lm = options_.method == Method::kLevenbergMarquardt;
  double radius = options_.initial_trust_region_radius;
  double decrease_factor = 2.0;
  Eigen::VectorXd damping(system_->size());
  Eigen::VectorXd& delta = delta_;
  Eigen::VectorXd& rhs = rhs_;
  const std::vector<int>& var_offset = system_->variable_offset();
  bool reuse_next = false;  // try the next step with the current factorization

  for (int iteration = 1;; ++iteration) {
    const double gradient_max = gradient_.cwiseAbs().maxCoeff();
    if (gradient_max <= options_.gradient_tolerance) {
      finish(TerminationType::kConvergence,
             "gradient tolerance reached: max |gradient| = " + number(gradient_max));
      break;
    }
    if (iteration > options_.max_iterations) {
      finish(TerminationType::kNoConvergence, iteration_limit_message(options_));
      break;
    }
    const Stopwatch iteration_time;
    ++summary_.num_iterations;
    IterationSummary row;
    row.iteration = iteration;
    row.gradient_max_norm = gradient_max;
    row.cost = cost_;

    if (reuse_next) {
      reuse_next = false;
      row.trust_region_radius = radius;
      bool stop = false;
      if (try_reused_factorization(row, iteration, iteration_time, &stop)) {
        if (stop) break;
        reuse_next = true;
        continue;
      }
    }

    // Damping: LM uses diag(H) clamped, scaled by 1/radius; GN none unless indefinite.
    const Eigen::VectorXd diag = system_->diagonal();
    const Eigen::VectorXd scaled_diag =
        diag.cwiseMax(options_.min_lm_diagonal).cwiseMin(options_.max_lm_diagonal);
    bool factorized = false;
    if (lm) {
      damping = scaled_diag / radius;
      const Stopwatch factor_time;
      factorized = system_->factorize(damping);
      summary_.time.numeric_s += factor_time.elapsed_s();
    } else {
      damping.setZero();
      for (double lambda = 0.0; lambda <= 1.0; lambda = (lambda == 0.0 ? 1e-12 : lambda * 100.0)) {
        damping = lambda * scaled_diag;
        const Stopwatch factor_time;
        factorized = system_->factorize(damping);
        summary_.time.numeric_s += factor_time.elapsed_s();
        if (factorized) break;
        row.linear_solver_failed = true;
        ++summary_.num_linear_solver_failures;
      }
    }
    if (!factorized) {
      if (lm) {
        row.linear_solver_failed = true;
        ++summary_.num_linear_solver_failures;
        ++summary_.num_unsuccessful_steps;
        radius /= decrease_factor;
        decrease_factor *= 2.0;
        row.trust_region_radius = radius;
        record(row, iteration_time);
        if (radius < options_.min_trust_region_radius) {
          finish(
              TerminationType::kNoConvergence,
              "trust region radius below min_trust_region_radius (system not positive definite)");
          break;
        }
        continue;
      }
      ++summary_.num_unsuccessful_steps;
      record(row, iteration_time);
      finish(TerminationType::kFailure,
             "Gauss-Newton: the system is not positive definite even with damping (gauge not fixed "
             "or rank-deficient H?)");
      break;
    }
    const Stopwatch solve_time;
    rhs = -gradient_;
    system_->solve(rhs, &delta);
    summary_.time.solve_s += solve_time.elapsed_s();
    row.step_norm = delta.norm();
    if (!delta.allFinite()) {
      row.linear_solver_failed = true;
      ++summary_.num_linear_solver_failures;
      ++summary_.num_unsuccessful_steps;
      record(row, iteration_time);
      finish(TerminationType::kFailure, "the linear solve produced a non-finite step");
      break;
    }

    const double x_norm = free_parameter_norm(problem_, var_offset, buffers_[current_].data());
    if (row.step_norm <= options_.parameter_tolerance * (x_norm + options_.parameter_tolerance)) {
      row.trust_region_radius = radius;
      ++summary_.num_unsuccessful_steps;  // the step is not taken
      record(row, iteration_time);
      finish(TerminationType::kConvergence,
             "parameter tolerance reached: |step| = " + number(row.step_norm));
      break;
    }

    const int trial = 1 - current_;
    apply_step(problem_, var_offset, buffers_[current_].data(), delta, buffers_[trial].data());
    const Stopwatch cost_time;
    const double new_cost = evaluator_->cost(trial);
    summary_.time.cost_s += cost_time.elapsed_s();

    // Predicted decrease of the quadratic model: -g.d - 1/2 d.H.d = 1/2 (-g.d + d.damping.d).
    const double model_decrease =
        0.5 * (-gradient_.dot(delta) + delta.dot(damping.cwiseProduct(delta)));
    const double actual_decrease = cost_ - new_cost;
    double ratio = model_decrease > 0.0 ? actual_decrease / model_decrease : -1.0;
    row.relative_decrease = ratio;
    // A predicted decrease below the rounding of the cost cannot be checked against the cost:
    // such a step is taken if the cost did not rise by more than that rounding, and counts as
    // a gain ratio of 1 (the gradient and parameter tests then decide convergence).
    const double rounding = cost_rounding(cost_);
    const bool below_rounding = model_decrease > 0.0 && model_decrease <= rounding &&
                                std::isfinite(new_cost) && actual_decrease >= -rounding;
    if (below_rounding) ratio = 1.0;
    const bool accept = std::isfinite(new_cost) &&
                        (lm ? ratio > options_.min_relative_decrease : new_cost <= cost_);
    if (accept) {
      ++summary_.num_successful_steps;
      row.step_is_successful = true;
      row.cost_change = actual_decrease;
      row.cost = new_cost;
      if (lm) {
        const double t = 2.0 * ratio - 1.0;
        radius =
            std::min(options_.max_trust_region_radius,
                     radius / std::max(1.0 / options_.max_trust_region_growth, 1.0 - t * t * t));
        decrease_factor = 2.0;
      }
      row.trust_region_radius = radius;
      // A gain ratio well above 1 (the cost fell faster than the model said, as in a slow,
      // linearly converging tail): the exact H buys little over this one, so the next step
      // first tries this factorization.
      // The ratio must be measured, not noise: its model decrease far above the rounding.
      reuse_next = lm && options_.reuse_factorization && ratio > options_.factor_reuse_ratio &&
                   model_decrease > 1e3 * rounding;
      if (take_step(row, new_cost, iteration, iteration_time)) break;
    } else {
      ++summary_.num_unsuccessful_steps;
      if (!lm) {
        record(row, iteration_time);
        finish(TerminationType::kNoConvergence, std::isfinite(new_cost)
                                                    ? "Gauss-Newton step did not decrease the cost"
                                                    : "Gauss-Newton step gave a non-finite cost");
        break;
      }
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      row.trust_region_radius = radius;
      record(row, iteration_time);
      if (radius < options_.min_trust_region_radius) {
        finish(TerminationType::kNoConvergence,
               "trust region radius below min_trust_region_radius");
        break;
      }
    }
  }
  summary_.final_cost = cost_;
}

}  // namespace

SolverSummary solve(const SolverOptions& options, Problem& problem) {
  const Stopwatch total_time;
  SolverSummary summary;
  summary.method =
      options.method == Method::kLevenbergMarquardt ? "levenberg_marquardt" : "gauss_newton";
  summary.num_threads = options.num_threads;
  std::string error;
  if (!options.validate(&error)) {
    summary.termination = TerminationType::kFailure;
    summary.message = "invalid options: " + error;
    return summary;
  }
  // More threads than TBB allows would only make TBB print a warning; clamp instead.
  SolverOptions effective = options;
  effective.num_threads = std::min(options.num_threads, tbb::info::default_concurrency());
  Solver solver(effective, problem, summary);
  tbb::task_arena arena(effective.num_threads);
  arena.execute([&] { solver.run(); });
  solver.write_back();
  summary.time.total_s = total_time.elapsed_s();
  return summary;
}

}  // namespace carat
