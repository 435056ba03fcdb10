#pragma once

// Internal: the linear system of one solver iteration, (H + diag(damping)) delta = rhs, behind
// one interface: sparse Cholesky of the whole system (SparseSystem) or the Schur complement
// that eliminates a group of variables first (SchurSystem). make_linear_system() picks one.

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "block_evaluator.hpp"
#include "block_linearizations.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "linearize_report.hpp"

namespace carat::internal {

class LinearSystem {
 public:
  virtual ~LinearSystem() = default;

  /// Scalar size n of the system (tangent dimensions of the free variables).
  int size() const { return n_; }
  /// Tangent offset of each variable in the system, -1 for constant variables.
  const std::vector<int>& variable_offset() const { return var_offset_; }
  /// Stored nonzeros of the matrix that is factorized (lower triangle).
  virtual std::size_t hessian_nonzeros() const = 0;
  /// Nonzeros of the Cholesky factor.
  virtual std::size_t factor_nonzeros() const = 0;
  /// Floating-point operations of one numeric factorization, as CHOLMOD's analysis counts them.
  virtual double factor_flops() const = 0;
  /// Name of the factorization and ordering for reports.
  const std::string& description() const { return description_; }

  /// Gathers blocks' H and b into the undamped system and the gradient (deterministic).
  virtual void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) = 0;

  /// Linearizes every block at the evaluator's buffer `which` and assembles the system and the
  /// gradient; reports the cost (1/2 sum rho) and the time of each stage, or, with ok false,
  /// the block and row that were not finite. The default evaluates into per-block storage,
  /// then assembles.
  virtual LinearizeReport linearize(const BlockEvaluator& evaluator, int which,
                                    Eigen::VectorXd* gradient);

  /// Adds the problem's block source at `values` to the assembled system and the gradient after
  /// the own blocks (their global indices start at first_index) and its costs to report->cost;
  /// false with report->error naming a block whose record is not finite. Only the whole sparse
  /// system takes a source: the default throws carat::Error.
  virtual bool add_source_blocks(BlockSource& source, std::span<const double> values,
                                 std::size_t first_index, Eigen::VectorXd* gradient,
                                 LinearizeReport* report);
  /// Undamped diagonal of H.
  virtual Eigen::VectorXd diagonal() const = 0;

  /// Factorizes H + diag(damping) numerically; false if not positive definite.
  virtual bool factorize(const Eigen::VectorXd& damping) = 0;

  /// y = H x with the undamped values of the last assembly.
  virtual void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const = 0;

  /// Solves (H + diag(damping)) x = rhs with the last successful factorization (which may be
  /// of an earlier assembly where reuses_factorization()).
  virtual void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) = 0;

  /// Whether solve() may use a factorization of an earlier assembly (SolverOptions::
  /// reuse_factorization applies only then).
  virtual bool reuses_factorization() const { return true; }

  /// The trust-region growth SolverOptions::max_trust_region_growth = 0 stands for here.
  virtual double automatic_trust_region_growth() const { return 10.0; }

  /// Seconds spent eliminating variables (forming the reduced system, back-substitution)
  /// since the last call; 0 for the whole-system path.
  virtual double take_elimination_seconds() { return 0.0; }

 protected:
  int n_ = 0;
  std::vector<int> var_offset_;
  BlockLinearizations storage_;  ///< per-block H and b of the default linearize()

  /// What linearize() does once the own blocks are assembled: sums their costs (storage_.cost,
  /// in block order) into report->cost, adds the block source's blocks, and sets report->ok
  /// unless one of those is not finite.
  void finish_linearize(const BlockEvaluator& evaluator, int which, Eigen::VectorXd* gradient,
                        LinearizeReport* report);
  std::string description_;
};

/// The system for `problem` under `options` (linear_solver, ordering). Throws carat::Error when
/// the Schur complement is asked for and no valid group of variables can be eliminated.
std::unique_ptr<LinearSystem> make_linear_system(const Problem& problem,
                                                 const SolverOptions& options);

}  // namespace carat::internal
