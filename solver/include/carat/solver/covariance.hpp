#pragma once

/// Marginal covariances of a problem's variables at its current values (e.g. after solve()):
/// blocks of H^-1, with H = J^T J the Gauss-Newton Hessian that solve() factorizes (robust losses
/// applied as solve() applies them, constant variables held fixed), in each variable's tangent
/// coordinates:
/// - SE(3): xi = [omega, v] (radians, then metres), T_world_body <- T_world_body * Exp(xi), so
///   the covariance is of the right (body-frame) perturbation;
/// - SE(2): xi = [omega, v_x, v_y] (radians, then metres), T <- T * Exp(xi) likewise;
/// - SO(3): omega, R <- R * Exp(omega); Euclidean variables: their own coordinates.
/// Compressed and lossless blocks reproduce their full blocks' H at the point they were
/// compressed at, so there the covariance is the full problem's.
///
/// The blocks come from the factorization solve() uses. With the whole system (sparse Cholesky)
/// every diagonal block and every pair of variables that share a residual block (more exactly:
/// every pair on the Cholesky factor's pattern) follow from the factor by the sparse-inverse
/// recursion (Takahashi et al.), in about the time of one factorization; any other pair costs
/// one triangular solve per column of the second variable. With the Schur complement (bundle
/// adjustment: eliminated points), the kept variables' blocks come the same way from the reduced
/// system's factor, and an eliminated variable's own block by back-substitution
/// (V^-1 + V^-1 W^T Sigma_cameras W V^-1, W its blocks with the cameras that see it).
///
/// A gauge freedom (no constant variable in a pose graph, bundle adjustment's similarity) makes H
/// singular. It is detected, never returned as NaN or as a huge finite number: a coordinate
/// whose variance H^-1(j, j) exceeds max_variance_inflation times 1 / H(j, j) (its variance with
/// every other coordinate held fixed) counts as free. Then, as Covariance::Options::gauge says,
/// either the constructor throws carat::Error naming the variables the free directions move, or
/// the blocks are those of the minimum-norm pseudo-inverse H^+ (the covariance with no variance
/// along the free directions, in the tangent coordinates above).

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/variable_id.hpp"

namespace carat {

/// What Covariance does when H is singular (a gauge freedom, an unobservable direction).
enum class CovarianceGauge {
  kError,          ///< throw carat::Error naming the variables the free directions move
  kPseudoInverse,  ///< the blocks of the minimum-norm pseudo-inverse H^+
};

/// Name of a gauge setting: "error" or "pseudo-inverse".
const char* to_string(CovarianceGauge gauge);
/// Parses "error" or "pseudo-inverse"; throws carat::Error listing them otherwise.
CovarianceGauge parse_covariance_gauge(std::string_view name);

/// Seconds spent by one Covariance.
struct CovarianceTimes {
  double linearize_s = 0.0;  ///< evaluating the blocks and assembling H
  double factorize_s = 0.0;  ///< numeric factorizations (and the symbolic analysis)
  double inverse_s = 0.0;    ///< the sparse inverse, the rank test and any gauge handling
  double total_s = 0.0;      ///< the constructor from start to end
};

/// Marginal covariances at a problem's current values (see the file comment). Constructing one
/// linearizes and factorizes the problem and computes the sparse inverse; the blocks are read
/// afterwards. It keeps no reference to the problem. Not safe to use from several threads at
/// once (a pair off the factor's pattern solves against the factor, which uses shared scratch).
class Covariance {
 public:
  /// Settings of the computation.
  struct Options {
    LinearSolver linear_solver = LinearSolver::kAuto;  ///< as SolverOptions::linear_solver
    Ordering ordering = Ordering::kAuto;               ///< as SolverOptions::ordering
    CovarianceGauge gauge = CovarianceGauge::kError;   ///< what a singular H leads to
    /// A coordinate whose variance exceeds this times its variance with every other coordinate
    /// held fixed (1 / H(j, j)) counts as free: H is treated as singular (> 1).
    double max_variance_inflation = 1e10;
    int num_threads = 1;  ///< threads for linearization (>= 1; capped at the machine's cores)
  };

  /// Computes the covariances of `problem` with default options. Throws carat::Error if a free
  /// variable is touched by no residual block, if a block is not finite at the current values,
  /// or if H is singular (naming the variables its free directions move).
  explicit Covariance(const Problem& problem);
  /// Same with `options` (also throws carat::Error for invalid options; with
  /// CovarianceGauge::kPseudoInverse a singular H is not an error).
  Covariance(const Problem& problem, const Options& options);
  ~Covariance();
  /// Movable, not copyable.
  Covariance(Covariance&&) noexcept;
  /// Movable, not copyable.
  Covariance& operator=(Covariance&&) noexcept;

  /// The covariance of a free variable: tangent_size() x tangent_size(), in its tangent
  /// coordinates. Throws carat::Error for a constant variable (it has none) or an invalid id.
  Eigen::MatrixXd block(VariableId id) const;

  /// The cross-covariance E[xi_a xi_b^T] of two free variables (a's tangent size rows, b's
  /// columns); block(a, a) == block(a). Throws carat::Error as block(id).
  Eigen::MatrixXd block(VariableId a, VariableId b) const;

  /// block(id) for each id, in order; a 0 x 0 matrix for a constant variable. Throws
  /// carat::Error for an invalid id.
  std::vector<Eigen::MatrixXd> blocks(std::span<const VariableId> ids) const;

  /// Whether block(a, b) is read from the sparse inverse (no solve): a == b, or the pair is on
  /// the factor's pattern. False for a constant variable.
  bool on_pattern(VariableId a, VariableId b) const;

  /// Dimension of the free directions removed under CovarianceGauge::kPseudoInverse (0 when H
  /// is nonsingular).
  int gauge_dimension() const;

  /// Tangent dimensions of the free variables (the order of H).
  int size() const;

  /// Where the construction's time went.
  const CovarianceTimes& time() const;

  /// The name of the factorization used ("cholmod supernodal, ..." or "schur complement ...").
  const std::string& description() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace carat
