#include "carat/solver/solve.hpp"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "block_evaluator.hpp"
#include "bound_constraints.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/solver/block_checker.hpp"
#include "factorization_reuse.hpp"
#include "hessian_damping.hpp"
#include "linear_system.hpp"
#include "solver_run.hpp"
#include "step_quality.hpp"
#include "stop_criteria.hpp"
#include "trust_region_strategy.hpp"

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

/// Euclidean norm of the free variables' values (ambient coordinates).
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

}  // namespace

namespace internal {

bool Solver::finish(TerminationType type, std::string message) {
  summary_.termination = type;
  summary_.message = std::move(message);
  return true;
}

void Solver::record(IterationSummary row, const Stopwatch& iteration_time) {
  row.iteration_time_s = iteration_time.elapsed_s();
  row.cumulative_time_s = solve_time_.elapsed_s();
  if (options_.record_iterations) summary_.iterations.push_back(row);
  if (options_.iteration_callback) {
    if (options_.update_state_every_iteration) write_back();
    if (options_.iteration_callback(row) == CallbackResult::kAbort) abort_requested_ = true;
  }
}

bool Solver::abort_if_requested() {
  if (!abort_requested_) return false;
  return finish(TerminationType::kUserAbort, "the iteration callback asked to stop");
}

bool Solver::linearize() {
  if (options_.evaluation_callback) options_.evaluation_callback({true, false});
  internal::LinearizeReport report = system_->linearize(*evaluator_, current_, &gradient_);
  summary_.time.linearize_s += report.time.linearize_s;
  summary_.time.assembly_s += report.time.assembly_s;
  if (!report.ok) return finish(TerminationType::kFailure, std::move(report.error)), false;
  cost_ = report.cost;
  return true;
}

/// Starts iteration `iteration` (counted, its row begun) unless the gradient tolerance or the
/// iteration limit ends the solve first: then false.
bool Solver::begin_iteration(int iteration, IterationSummary* row) {
  if (abort_if_requested()) return false;
  double gradient_max = gradient_.cwiseAbs().maxCoeff();
  if (bounds_) {  // what can still move: the projected gradient
    Eigen::VectorXd projected = gradient_;
    bounds_->project_gradient(buffers_[current_].data(), &projected);
    gradient_max = projected.cwiseAbs().maxCoeff();
  }
  std::optional<internal::StopReason> stop =
      internal::check_gradient_tolerance(gradient_max, options_.gradient_tolerance);
  if (!stop) stop = internal::check_iteration_limit(iteration - 1, options_.max_iterations);
  if (stop) {
    finish(std::move(*stop));
    return false;
  }
  ++summary_.num_iterations;
  row->iteration = iteration;
  row->gradient_max_norm = gradient_max;
  row->cost = cost_;
  return true;
}

/// Numeric factorization of H + diag(damping_). False: not positive definite.
bool Solver::factorize() {
  const Stopwatch t0;
  const bool factorized = system_->factorize(damping_);
  const double elimination_s = system_->take_elimination_seconds();
  summary_.time.schur_s += elimination_s;
  summary_.time.numeric_s += t0.elapsed_s() - elimination_s;
  return factorized;
}

/// Gauss-Newton's factorization: undamped, or with the smallest damping of
/// gauss_newton_damping_factors() that makes the system positive definite. Each failed
/// attempt is counted and marked in the row. False: none succeeded.
bool Solver::factorize_gauss_newton(IterationSummary* row) {
  const Eigen::VectorXd diagonal =
      internal::clamped_hessian_diagonal(system_->diagonal(), options_);
  for (const double lambda : internal::gauss_newton_damping_factors()) {
    damping_ = lambda * diagonal;
    if (bounds_) bounds_->hold_active(buffers_[current_].data(), gradient_, &damping_);
    if (factorize()) return true;
    row->linear_solver_failed = true;
    ++summary_.num_linear_solver_failures;
  }
  return false;
}

/// Solves the factorized system for the step delta_ = -(H + damping)^-1 gradient. False (the
/// row recorded, the solve ended as a failure): the step is not finite.
bool Solver::solve_for_step(IterationSummary& row, const Stopwatch& iteration_time) {
  const Stopwatch t0;
  rhs_ = -gradient_;
  system_->solve(rhs_, &delta_);
  const double elimination_s = system_->take_elimination_seconds();
  summary_.time.schur_s += elimination_s;
  summary_.time.solve_s += t0.elapsed_s() - elimination_s;
  row.step_norm = delta_.norm();
  if (delta_.allFinite()) return true;
  row.linear_solver_failed = true;
  ++summary_.num_linear_solver_failures;
  ++summary_.num_unsuccessful_steps;
  record(row, iteration_time);
  finish(TerminationType::kFailure, "the linear solve produced a non-finite step");
  return false;
}

/// True (the row recorded with `radius`, the solve ended) when the step in delta_ meets the
/// parameter tolerance; the step is then not taken.
bool Solver::stop_on_small_step(IterationSummary& row, double radius,
                                const Stopwatch& iteration_time) {
  const double x_norm =
      free_parameter_norm(problem_, system_->variable_offset(), buffers_[current_].data());
  std::optional<internal::StopReason> stop =
      internal::check_parameter_tolerance(row.step_norm, x_norm, options_.parameter_tolerance);
  if (!stop) return false;
  row.trust_region_radius = radius;
  ++summary_.num_unsuccessful_steps;
  record(row, iteration_time);
  return finish(std::move(*stop));
}

/// Writes current [+] delta_ into the other buffer and returns its cost. `predicted`: the
/// decrease the evaluation callback's likely_final hint weighs (negative: delta_'s own, as
/// solved from the damped system); kept in hint_decrease_.
double Solver::trial_cost(double predicted) {
  const int trial = 1 - current_;
  apply_step(problem_, system_->variable_offset(), buffers_[current_].data(), delta_,
             buffers_[trial].data());
  projected_ = bounds_ && bounds_->project(buffers_[trial].data());
  if (projected_) {  // the step taken is the projected one: trial [-] current
    const auto& offset = system_->variable_offset();
    for (int v = 0; v < problem_.num_variables(); ++v) {
      const int t = offset[static_cast<std::size_t>(v)];
      if (t < 0) continue;
      const VariableId id{v};
      const std::size_t at = problem_.value_offset(id);
      problem_.manifold(id).minus(buffers_[trial].data() + at, buffers_[current_].data() + at,
                                  delta_.data() + t);
    }
  }
  if (options_.evaluation_callback) {
    // The step ends the solve if it meets the function tolerance (take_step()): likely so when
    // the model predicts that much; or when no iteration follows.
    const bool last = summary_.num_iterations >= options_.max_iterations;
    if (predicted < 0.0) predicted = internal::damped_model_decrease(gradient_, delta_, damping_);
    hint_decrease_ = predicted;
    const bool small = !projected_ && predicted <= options_.function_tolerance * cost_;
    options_.evaluation_callback({false, last || small});
  }
  const Stopwatch t0;
  const double cost = evaluator_->cost(trial);
  summary_.time.cost_s += t0.elapsed_s();
  return cost;
}

/// The decrease the model predicts for the step in delta_: the damped model's (exact for the
/// solution of the damped system), or, for a step projected onto the bounds, the undamped
/// quadratic model's at the projected step.
double Solver::predicted_decrease() {
  if (!projected_) return internal::damped_model_decrease(gradient_, delta_, damping_);
  system_->multiply(delta_, &h_delta_);
  return internal::model_decrease(gradient_, delta_, h_delta_);
}

/// Moves to the trial iterate (cost new_cost) and relinearizes there, unless the solve ends with
/// this step: after the last permitted iteration, or when the step meets the function tolerance,
/// nothing would use that H and b (a one-iteration solve, as align() runs per correspondence
/// set, costs one linearization instead of two; Ceres also skips this evaluation), so the
/// gradient there is not tested either. Records the row. True: the solve ends.
bool Solver::take_step(IterationSummary& row, double new_cost, int iteration,
                       const Stopwatch& iteration_time) {
  const double old_cost = cost_;
  const double decrease = old_cost - new_cost;
  if (!row.reused_factorization) fresh_decrease_ = decrease;
  current_ = 1 - current_;
  std::optional<internal::StopReason> stop =
      internal::check_function_tolerance(decrease, old_cost, options_.function_tolerance);
  if (!stop) stop = internal::check_iteration_limit(iteration, options_.max_iterations);
  if (stop) {
    cost_ = new_cost;
    record(row, iteration_time);
    return finish(std::move(*stop));
  }
  if (!linearize()) {
    record(row, iteration_time);
    return true;
  }
  record(row, iteration_time);
  return false;
}

/// LM: a step not taken (its gain ratio too low, or the system not positive definite). The
/// trust region shrinks and the row is recorded. True: the radius collapsed and the solve ends.
bool Solver::reject_step(IterationSummary& row, internal::TrustRegionStrategy& region,
                         internal::RadiusShrinkCause cause, const Stopwatch& iteration_time) {
  ++summary_.num_unsuccessful_steps;
  region.on_rejected();
  row.trust_region_radius = region.radius();
  record(row, iteration_time);
  std::optional<internal::StopReason> stop =
      internal::check_trust_region_radius(region.radius(), options_.min_trust_region_radius, cause);
  return stop && finish(std::move(*stop));
}

/// With delta_ the solved step and the trial buffer at current [+] delta_ (cost *new_cost,
/// judged as *step): in an accelerated tail, if Anderson's method proposes a step of lower cost,
/// delta_ and the trial buffer become that step, *new_cost its cost, *step keeps the solved
/// step's ratio (how well the factorization serves) with the decrease achieved, and the result
/// is true; otherwise nothing changes. solved_ is the solved step either way.
bool Solver::accelerate(double* new_cost, internal::StepQuality* step) {
  solved_ = delta_;
  if (!accelerated_tail_ || !anderson_.propose(solved_, &accelerated_)) return false;
  delta_.swap(accelerated_);
  // The hint weighs the solved step's prediction: the combination has no model of its own.
  const double cost = trial_cost(hint_decrease_);
  if (cost < *new_cost) {  // false for a NaN cost
    *new_cost = cost;
    step->cost_decrease = cost_ - cost;
    return true;
  }
  // Back to the solved step: its cost is known, so the trial point is rebuilt, not evaluated.
  delta_ = solved_;
  apply_step(problem_, system_->variable_offset(), buffers_[current_].data(), delta_,
             buffers_[1 - current_].data());
  return false;
}

/// After a step of LM: a rejected one ends an accelerated tail; an accepted slow-tail step starts
/// one (when anderson_memory > 0 and there are no bounds, which a combination could leave); an
/// accepted step in a tail is recorded (solved_, delta_) for Anderson's method.
void Solver::enter_or_leave_tail(bool accepted, const internal::StepQuality& step) {
  if (!accepted) {
    accelerated_tail_ = false;
    anderson_.reset();
    return;
  }
  if (!accelerated_tail_ && options_.anderson_memory > 0 && !bounds_ &&
      internal::is_slow_tail_step(step, options_)) {
    accelerated_tail_ = true;
    anderson_ = internal::AndersonAcceleration(options_.anderson_memory);
  }
  if (accelerated_tail_) anderson_.push(solved_, delta_);
}

/// A step solved with the factorization of an earlier iterate: no numeric factorization, only
/// a triangular solve, H delta for the model at the current iterate, and one cost evaluation
/// (two in an accelerated tail, where accelerate() may replace it). Kept by the rule that
/// applies: in an accelerated tail keeps_accelerated_tail_step(); otherwise keeps_reused_step()
/// (a run of reused steps ends once they fall to half of what a fresh one achieved); a
/// convergence probe only when probe_converged() says the solve is over (take_step() then
/// stops on the function tolerance). Then returns true (*stop: the solve ends); otherwise
/// nothing is recorded and the caller factorizes afresh.
bool Solver::try_reused_factorization(IterationSummary& row, int iteration,
                                      const Stopwatch& iteration_time, bool convergence_probe,
                                      bool* stop) {
  const Stopwatch ts;
  rhs_ = -gradient_;
  system_->solve(rhs_, &delta_);
  if (delta_.allFinite()) system_->multiply(delta_, &h_delta_);
  const double elimination_s = system_->take_elimination_seconds();
  summary_.time.schur_s += elimination_s;
  summary_.time.solve_s += ts.elapsed_s() - elimination_s;
  if (!delta_.allFinite()) {
    ++summary_.num_refused_reuses;
    return false;
  }
  const double predicted = internal::model_decrease(gradient_, delta_, h_delta_);
  double new_cost = trial_cost();
  internal::StepQuality step = internal::judge_step(cost_, new_cost, predicted);
  const bool accelerated = !convergence_probe && accelerate(&new_cost, &step);
  // A convergence probe is kept only when it ends the solve; other reused steps by the rule of
  // an accelerated tail or of slow tails.
  const bool keep =
      convergence_probe ? internal::probe_converged(step, cost_, options_.function_tolerance)
      : accelerated_tail_
          ? internal::keeps_accelerated_tail_step(step, fresh_decrease_, cost_,
                                                  options_.function_tolerance)
          : internal::keeps_reused_step(step, fresh_decrease_, cost_, options_.function_tolerance);
  if (!keep) {
    ++summary_.num_refused_reuses;
    return false;
  }
  row.accelerated = accelerated;
  if (accelerated) ++summary_.num_accelerated_steps;
  enter_or_leave_tail(true, step);
  ++summary_.num_successful_steps;
  ++summary_.num_reused_factorizations;
  row.step_norm = delta_.norm();
  row.relative_decrease = step.measured_ratio;
  row.cost_change = step.cost_decrease;
  row.cost = new_cost;
  row.step_is_successful = true;
  row.reused_factorization = true;
  *stop = take_step(row, new_cost, iteration, iteration_time);
  return true;
}

/// The symbolic analysis, the buffers and the first linearization; the summary's problem
/// figures and the row of iteration 0. False: the solve is already over.
bool Solver::initialize() {
  summary_.num_threads = options_.num_threads;
  summary_.method =
      options_.method == Method::kLevenbergMarquardt ? "levenberg_marquardt" : "gauss_newton";
  summary_.num_variables = problem_.num_variables();
  summary_.num_residual_blocks = static_cast<int>(problem_.num_all_blocks());
  summary_.num_residual_rows = problem_.num_residual_rows();
  if (problem_.block_source())
    summary_.num_residual_rows += problem_.block_source()->num_residual_rows();
  summary_.residual_memory_bytes = problem_.residual_memory_bytes();
  for (int v = 0; v < problem_.num_variables(); ++v) {
    if (!problem_.is_constant(VariableId{v})) ++summary_.num_free_variables;
  }

  if (options_.check_blocks) {
    const ProblemCheckReport check = check_problem(problem_);
    if (!check.ok) {
      finish(TerminationType::kFailure, "check_blocks: " + check.summary());
      return false;
    }
  }
  Stopwatch t0;
  try {
    system_ = internal::make_linear_system(problem_, options_);
  } catch (const Error& e) {
    summary_.time.symbolic_s += t0.elapsed_s();
    finish(TerminationType::kFailure, e.what());
    return false;
  }
  summary_.time.symbolic_s += t0.elapsed_s();
  if (options_.max_trust_region_growth == 0.0) {
    options_.max_trust_region_growth = system_->automatic_trust_region_growth();
  }
  summary_.trust_region_growth = options_.max_trust_region_growth;
  if (options_.lm_start == LmStart::kAuto) options_.lm_start = LmStart::kGaussNewton;
  if (!system_->reuses_factorization()) options_.reuse_factorization = false;
  summary_.num_tangent_parameters = system_->size();
  summary_.hessian_nonzeros = system_->hessian_nonzeros();
  summary_.factor_nonzeros = system_->factor_nonzeros();
  summary_.factor_flops = system_->factor_flops();
  summary_.linear_solver = system_->description();

  const auto values = problem_.all_values();
  buffers_[0].assign(values.begin(), values.end());
  buffers_[1] = buffers_[0];
  if (problem_.has_bounds()) {
    bounds_ = std::make_unique<internal::BoundConstraints>(problem_, system_->variable_offset());
    const std::string outside = bounds_->outside(buffers_[0].data());
    if (!outside.empty()) {
      finish(TerminationType::kFailure, "the initial value is outside the bounds: " + outside);
      return false;
    }
    if (bounds_->empty()) bounds_.reset();
    options_.reuse_factorization = false;  // a reused factor would ignore the active set
  }
  evaluator_ = std::make_unique<internal::BlockEvaluator>(problem_);
  for (int k = 0; k < 2; ++k) evaluator_->bind(k, buffers_[k].data());

  const Stopwatch iteration0;
  if (!linearize()) return false;
  summary_.initial_cost = cost_;
  summary_.final_cost = cost_;
  if (!std::isfinite(cost_)) {
    finish(TerminationType::kFailure, "the initial cost is not finite");
    return false;
  }
  IterationSummary row0;
  row0.cost = cost_;
  row0.gradient_max_norm = gradient_.size() ? gradient_.cwiseAbs().maxCoeff() : 0.0;
  row0.trust_region_radius =
      options_.method == Method::kLevenbergMarquardt && options_.lm_start == LmStart::kGaussNewton
          ? options_.gauss_newton_phase_radius
          : options_.initial_trust_region_radius;
  row0.step_is_successful = true;
  record(row0, iteration0);
  if (abort_if_requested()) return false;

  if (system_->size() == 0) {
    finish(TerminationType::kConvergence, "no free variables: nothing to optimize");
    return false;
  }
  return true;
}

void Solver::run() {
  if (!initialize()) return;
  if (options_.method == Method::kLevenbergMarquardt) {
    run_levenberg_marquardt();
  } else {
    run_gauss_newton();
  }
  summary_.final_cost = cost_;
}

}  // namespace internal

SolverSummary solve(const SolverOptions& options, Problem& problem) {
  const Stopwatch start;
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
  internal::Solver solver(effective, problem, summary);
  tbb::task_arena arena(effective.num_threads);
  arena.execute([&] { solver.run(); });
  solver.write_back();
  summary.time.total_s = start.elapsed_s();
  return summary;
}

}  // namespace carat
