#pragma once

/// What a solve did: costs, per-iteration rows, a time breakdown, and why it stopped.

#include <cstddef>
#include <string>
#include <vector>

namespace carat {

/// Why the solver stopped.
enum class TerminationType {
  kConvergence,    ///< a function, gradient or parameter tolerance was met
  kNoConvergence,  ///< max_iterations reached, or the trust region collapsed
  kFailure,        ///< invalid options or problem, or no usable step could be computed
  kUserAbort,      ///< SolverOptions::iteration_callback asked to stop (last accepted iterate kept)
};

/// Name of a termination type ("CONVERGENCE", "NO_CONVERGENCE", "FAILURE", "USER_ABORT").
const char* to_string(TerminationType type);

/// One row of the iteration table.
struct IterationSummary {
  int iteration = 0;                  ///< 0 is the initial evaluation
  double cost = 0.0;                  ///< cost after this iteration (1/2 sum rho)
  double cost_change = 0.0;           ///< decrease of the cost achieved by the step (0 if rejected)
  double gradient_max_norm = 0.0;     ///< max |b| at the iterate the step started from
  double step_norm = 0.0;             ///< |delta| of the step tried
  double relative_decrease = 0.0;     ///< gain ratio actual / predicted decrease
  double trust_region_radius = 0.0;   ///< LM radius mu after this iteration
  bool step_is_successful = false;    ///< step accepted
  bool linear_solver_failed = false;  ///< the damped system was not positive definite
  bool reused_factorization = false;  ///< step solved with an earlier iterate's factorization
  /// The step taken is Anderson's combination of recent steps (relative_decrease stays the
  /// solved step's, which the trust region judges; cost_change is the combination's)
  bool accelerated = false;
  double iteration_time_s = 0.0;   ///< wall time of this iteration
  double cumulative_time_s = 0.0;  ///< wall time since solve() started
};

/// Wall time per stage, summed over the solve, in seconds.
struct TimeBreakdown {
  double linearize_s = 0.0;  ///< evaluating blocks' H, b, c (parallel)
  double cost_s = 0.0;       ///< evaluating the cost of trial steps
  double assembly_s = 0.0;   ///< scattering block values into the sparse matrix
  double symbolic_s = 0.0;   ///< pattern, ordering and CHOLMOD symbolic analysis (once)
  double numeric_s = 0.0;    ///< CHOLMOD numeric factorizations
  double solve_s = 0.0;      ///< triangular solves
  double schur_s = 0.0;      ///< Schur complement: eliminating variables, back-substitution
  double total_s = 0.0;      ///< whole solve() call
};

/// The result of one solve.
struct SolverSummary {
  TerminationType termination = TerminationType::kFailure;  ///< why it stopped
  std::string message;                                      ///< human-readable reason
  double initial_cost = 0.0;                                ///< cost at the start
  double final_cost = 0.0;                                  ///< cost of the returned (best) iterate
  int num_iterations = 0;              ///< iterations run (accepted + rejected)
  int num_successful_steps = 0;        ///< accepted steps
  int num_unsuccessful_steps = 0;      ///< rejected steps
  int num_reused_factorizations = 0;   ///< accepted steps solved with an earlier factorization
  int num_accelerated_steps = 0;       ///< accepted steps that took Anderson's combination
  int num_refused_reuses = 0;          ///< steps with an earlier factorization tried and not kept
  int num_linear_solver_failures = 0;  ///< factorizations that were not positive definite
  int num_variables = 0;               ///< variables in the problem
  int num_free_variables = 0;          ///< variables not held constant
  int num_tangent_parameters = 0;      ///< size of the linear system
  int num_residual_blocks = 0;         ///< residual blocks
  std::size_t num_residual_rows = 0;   ///< scalar residual rows
  std::size_t factor_nonzeros = 0;     ///< nonzeros of the Cholesky factor
  /// Floating-point operations of one numeric factorization (CHOLMOD's count for the chosen
  /// ordering); with time.numeric_s and the factorizations (iterations - reused), the flop rate.
  double factor_flops = 0.0;
  std::size_t hessian_nonzeros = 0;          ///< stored nonzeros of the upper triangle of H
  std::size_t residual_memory_bytes = 0;     ///< bytes held by residual blocks
  int num_threads = 1;                       ///< threads used for linearization
  std::string method;                        ///< "levenberg_marquardt" or "gauss_newton"
  std::string linear_solver;                 ///< e.g. "cholmod_supernodal (block_amd)"
  double trust_region_growth = 0.0;          ///< LM's largest radius growth per step, as used
  TimeBreakdown time;                        ///< where the time went
  std::vector<IterationSummary> iterations;  ///< one row per iteration (iteration 0 first)

  /// True when the returned values are usable (converged or ran out of iterations).
  bool is_solution_usable() const { return termination != TerminationType::kFailure; }
  /// One line: method, costs, iterations, termination, time.
  std::string brief_report() const;
  /// The iteration table and a stage-by-stage breakdown (Ceres FullReport style).
  std::string full_report() const;
  /// The iteration table alone (header plus one row per iteration).
  std::string iteration_table() const;
  /// One JSON object with every field above.
  std::string to_json() const;
};

/// Adds `later`, a later solve of the same job (e.g. the next round of a registration that
/// re-searches its correspondences), to `total`: step counts and stage times are summed; the
/// iteration rows are appended, numbered on and with cumulative times continued; the end state
/// (termination, message, final cost) and what describes the problem and the setup (sizes, bytes,
/// threads, method, linear solver, growth) are `later`'s; the initial cost stays `total`'s.
/// A `total` with no iterations yet (`num_iterations == 0` and no rows) becomes `later`.
void merge_later_solve(SolverSummary& total, const SolverSummary& later);

}  // namespace carat
