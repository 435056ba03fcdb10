#pragma once

/// Settings of the nonlinear least-squares solver (defaults follow Ceres where it has one).

#include <functional>
#include <string>
#include <string_view>

#include "carat/solver/solver_summary.hpp"

namespace carat {

/// The outer nonlinear method.
enum class Method {
  kLevenbergMarquardt,  ///< trust region with diag(H) damping (Ceres-style)
  kGaussNewton,         ///< undamped steps; damping only to recover from an indefinite system
};

/// Name of a method: "lm" (Levenberg-Marquardt) or "gn" (Gauss-Newton).
const char* to_string(Method method);
/// Parses "lm" or "gn"; throws carat::Error listing them otherwise.
Method parse_method(std::string_view name);

/// How Levenberg-Marquardt begins. In the Gauss-Newton phase the radius is
/// gauss_newton_phase_radius (damping 1e-10 clamped diag(H): steps all but undamped, yet a gauge
/// freedom's directions stay positive definite) for as long as every step's gain ratio is at
/// least gauss_newton_phase_min_gain; the first step below it (taken if min_relative_decrease
/// accepts it), a rejected step or a system that is not positive definite ends the phase, and
/// LM goes on from initial_trust_region_radius as a solve that started there. The phase pays
/// where Gauss-Newton converges from the start (pose graphs from odometry, bundle adjustment
/// from a fair start: 5-85 % fewer iterations, measured in docs/benchmarks.md) and costs one
/// factorization where it does not.
enum class LmStart {
  kAuto,         ///< the Gauss-Newton phase on every path (the choice may become per path)
  kGaussNewton,  ///< the Gauss-Newton phase, then the trust region from its initial radius
  kTrustRegion,  ///< the trust region from initial_trust_region_radius (Ceres's start)
};

/// Name of an LM start: "auto", "gauss_newton" or "trust_region".
const char* to_string(LmStart start);
/// The LM start named by to_string(LmStart); throws carat::Error naming the valid names.
LmStart parse_lm_start(std::string_view name);

/// Fill-reducing ordering of the matrix that is factorized, computed once in the symbolic
/// analysis: for the whole system on the variable-level graph (then expanded to scalars and
/// postordered), for the Schur complement on the reduced system.
enum class Ordering {
  kAuto,   ///< AMD; where AMD's factor holds at least 4 times the analyzed triangle's
           ///< nonzeros, METIS and CHOLMOD's NESDIS are tried too and the one whose factor
           ///< needs the fewest flops is kept (AMD on a tie); the same rule for the whole system
           ///< and the Schur complement's reduced system
  kAmd,    ///< approximate minimum degree
  kMetis,  ///< METIS nested dissection (good for large, mesh-like graphs)
};

/// Name of an ordering: "auto", "amd" or "metis".
const char* to_string(Ordering ordering);
/// Parses "auto", "amd" or "metis"; throws carat::Error listing them otherwise.
Ordering parse_ordering(std::string_view name);

/// How the linear system of each iteration is solved.
enum class LinearSolver {
  kAuto,      ///< Schur complement when a group of variables can be eliminated (see solve())
              ///< and its reduced system takes at most twice the whole system's memory (a
              ///< reduced system made dense by shared points can take far more) and fits
              ///< SolverOptions::max_linear_system_bytes; else sparse Cholesky of the whole system
  kSchur,     ///< eliminate the eliminable variables (Problem::set_eliminable(), or the group
              ///< kAuto would pick), then sparse Cholesky of the reduced system
  kCholesky,  ///< sparse Cholesky (CHOLMOD supernodal) of the whole system
};

/// Name of a linear solver: "auto", "schur" or "cholesky".
const char* to_string(LinearSolver solver);
/// Parses "auto", "schur" or "cholesky"; throws carat::Error listing them otherwise.
LinearSolver parse_linear_solver(std::string_view name);

/// What an iteration callback asks of the solver.
enum class CallbackResult {
  kContinue,  ///< go on
  kAbort,     ///< stop before the next iteration: TerminationType::kUserAbort, the last
              ///< accepted iterate kept (as Ceres's SOLVER_ABORT)
};

/// Called after every iteration with its row (iteration 0 is the initial evaluation).
using IterationCallback = std::function<CallbackResult(const IterationSummary&)>;

/// What a pass over the residual blocks is for (see SolverOptions::evaluation_callback).
struct EvaluationHint {
  bool jacobians = false;  ///< the pass linearizes (else it evaluates the cost alone)
  /// A cost pass at a trial point after which the solve will likely end without linearizing
  /// there: the model's predicted decrease already meets function_tolerance, or the iteration is
  /// the last permitted. A hint: the solve may go on all the same.
  bool likely_final = false;
};

/// Called before each pass over the residual blocks (as Ceres's EvaluationCallback).
using EvaluationCallback = std::function<void(const EvaluationHint&)>;

/// What solve() does and when it stops.
struct SolverOptions {
  Method method = Method::kLevenbergMarquardt;       ///< nonlinear method
  Ordering ordering = Ordering::kAuto;               ///< fill-reducing ordering
  LinearSolver linear_solver = LinearSolver::kAuto;  ///< whole system or Schur complement
  /// Most memory the linear system may take, bytes (its matrix and factor; for the Schur
  /// complement also the reduced system and the eliminated blocks), estimated from the fill of
  /// a symbolic analysis before anything of that size is allocated; 0: 80 % of the memory
  /// available (carat::available_memory_bytes()). kAuto picks the system that fits; a system
  /// that does not fit ends the solve with FAILURE and the estimate in the message.
  double max_linear_system_bytes = 0.0;
  int max_iterations = 50;                   ///< iterations (accepted or not) before giving up
  double function_tolerance = 1e-6;          ///< stop when |cost change| / cost < this
  double gradient_tolerance = 1e-10;         ///< stop when max |gradient| < this
  double parameter_tolerance = 1e-8;         ///< stop when |step| < this * (|x| + this)
  double initial_trust_region_radius = 1e4;  ///< LM: initial radius mu (damping is 1/mu)
  LmStart lm_start = LmStart::kAuto;         ///< LM: how the trust region begins (LmStart)
  double gauss_newton_phase_radius = 1e10;   ///< LM: the radius mu during the Gauss-Newton phase
  double gauss_newton_phase_min_gain = 0.5;  ///< LM: lowest gain ratio that stays in the phase
  double max_trust_region_radius = 1e16;     ///< LM: largest radius
  /// LM: most the radius can grow after one step: radius / max(1 / this, 1 - (2 rho - 1)^3)
  /// for gain ratio rho; 0 (automatic): 10 when the whole system is factorized (pose graphs
  /// reach undamped steps sooner), 3, Ceres's value, with the Schur complement (bundle
  /// adjustment's model is less exact: 10 there ends some solves early at a higher cost).
  double max_trust_region_growth = 0.0;
  double min_trust_region_radius = 1e-32;  ///< LM: stop when the radius falls below this
  double min_relative_decrease = 1e-3;     ///< LM: smallest gain ratio that accepts a step
  double min_lm_diagonal = 1e-6;           ///< LM: lower clamp of diag(H) in the damping
  double max_lm_diagonal = 1e32;           ///< LM: upper clamp of diag(H) in the damping
  /// LM: after an accepted step whose gain ratio exceeded factor_reuse_ratio, try the next step
  /// with the previous numeric factorization (see solve()); false always factorizes afresh.
  bool reuse_factorization = true;
  double factor_reuse_ratio = 1.1;  ///< LM: gain ratio above which a reuse is tried
  /// LM, slow tails: from an accepted step whose gain ratio exceeds factor_reuse_ratio until a
  /// step is rejected, each step is also tried as Anderson's combination of the last
  /// `anderson_memory` steps and taken if that lowers the cost more, and each next step first
  /// tries the previous factorization (see solve()); 0: off. At most 64. The tail holds 2 x
  /// anderson_memory vectors of the tangent size, and as much again while it combines them.
  int anderson_memory = 5;
  int num_threads = 1;  ///< threads for linearization (>= 1; capped at the machine's cores)
  bool record_iterations = true;  ///< keep one IterationSummary per iteration
  /// Called after every iteration, on the thread that called solve(), whether or not rows are
  /// recorded; kAbort ends the solve. An exception it throws propagates out of solve(), and the
  /// problem keeps the values it had before the solve (or the iterate last written for a
  /// callback). Empty: none.
  IterationCallback iteration_callback;
  /// Called before each pass over the residual blocks, on the thread that called solve(), with
  /// what the pass is for: blocks that evaluate ahead (carat's Python rows ask a function for
  /// its Jacobians with its residuals) can skip work the solve will not use. Empty: none.
  EvaluationCallback evaluation_callback;
  /// During each iteration_callback call the problem's variables hold the current iterate (the
  /// last accepted one), as Ceres's update_state_every_iteration; else only after the solve.
  bool update_state_every_iteration = false;
  /// Before the first iteration, run check_problem() (block_checker.hpp: the row contract and
  /// the Jacobian against numeric differences, on the first block of every distinct type); a
  /// block that fails ends the solve with TerminationType::kFailure and the report as message.
  /// On by default in builds without NDEBUG (debug builds of the code that includes this), off
  /// otherwise: it costs 2 D + 2 evaluations of each checked block.
#ifdef NDEBUG
  bool check_blocks = false;
#else
  bool check_blocks = true;
#endif

  /// True if every setting is in range; otherwise false with a message in *error.
  bool validate(std::string* error) const;
};

}  // namespace carat
