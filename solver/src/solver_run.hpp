#pragma once

// Internal: one solve's state and the pieces of its iterations (solve.cpp), driven by one short
// loop per method (solver_methods.cpp).

#include <Eigen/Core>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "anderson_acceleration.hpp"
#include "block_evaluator.hpp"
#include "bound_constraints.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/solver_summary.hpp"
#include "linear_system.hpp"
#include "stop_criteria.hpp"
#include "trust_region_strategy.hpp"

namespace carat::internal {

/// One solve: set-up and the first linearization, then the iterations of the chosen method.
/// Levenberg-Marquardt and Gauss-Newton share the pieces of an iteration (the stop tests at its
/// start, the linear solve, the parameter test, the trial cost, moving to the new iterate);
/// the trust region, its damping and the reuse of factorizations belong to LM alone.
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
  bool initialize();
  void run_levenberg_marquardt();
  void run_gauss_newton();
  bool begin_iteration(int iteration, IterationSummary* row);
  bool factorize();
  bool factorize_gauss_newton(IterationSummary* row);
  bool solve_for_step(IterationSummary& row, const Stopwatch& iteration_time);
  bool stop_on_small_step(IterationSummary& row, double radius, const Stopwatch& iteration_time);
  double trial_cost(double predicted = -1.0);
  double predicted_decrease();
  bool accelerate(double* new_cost, internal::StepQuality* step);
  void enter_or_leave_tail(bool accepted, const internal::StepQuality& step);
  bool reject_step(IterationSummary& row, internal::TrustRegionStrategy& region,
                   internal::RadiusShrinkCause cause, const Stopwatch& iteration_time);
  bool linearize();
  bool take_step(IterationSummary& row, double new_cost, int iteration,
                 const Stopwatch& iteration_time);
  bool try_reused_factorization(IterationSummary& row, int iteration,
                                const Stopwatch& iteration_time, bool convergence_probe,
                                bool* stop);
  void record(IterationSummary row, const Stopwatch& iteration_time);
  bool finish(TerminationType type, std::string message);
  /// Ends the solve with kUserAbort when the iteration callback asked for it: then true.
  bool abort_if_requested();
  bool finish(internal::StopReason reason) {
    return finish(reason.type, std::move(reason.message));
  }

  SolverOptions options_;  ///< a copy: the automatic trust-region growth is resolved in it
  Problem& problem_;
  SolverSummary& summary_;
  Stopwatch solve_time_;  ///< since the solver was made
  std::unique_ptr<internal::LinearSystem> system_;
  std::unique_ptr<internal::BlockEvaluator> evaluator_;
  std::unique_ptr<internal::BoundConstraints> bounds_;  ///< none when the problem has no bounds
  bool projected_ = false;  ///< the last trial point was moved onto the bounds
  std::vector<double> buffers_[2];
  int current_ = 0;
  bool abort_requested_ = false;  ///< the iteration callback returned kAbort
  double cost_ = 0.0;
  double fresh_decrease_ = 0.0;  ///< cost decrease of the last step from a fresh factorization
  Eigen::VectorXd gradient_;
  Eigen::VectorXd damping_;  ///< diagonal added to H in the last factorization
  Eigen::VectorXd delta_;    ///< scratch: the step
  Eigen::VectorXd rhs_;      ///< scratch: -gradient
  Eigen::VectorXd h_delta_;  ///< scratch: H delta
  /// An accelerated tail (SolverOptions::anderson_memory) is running: from a slow-tail step
  /// until a step is rejected.
  bool accelerated_tail_ = false;
  internal::AndersonAcceleration anderson_{0};  ///< the tail's recent steps
  Eigen::VectorXd solved_;       ///< scratch: the step solved, before any acceleration
  Eigen::VectorXd accelerated_;  ///< scratch: Anderson's step
  double hint_decrease_ = 0.0;   ///< the decrease the last trial's likely_final hint weighed
};

}  // namespace carat::internal
