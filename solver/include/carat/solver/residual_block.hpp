#pragma once

/// The residual block contract. A block touches a few variables and has num_rows() scalar
/// residuals r_k. Its cost is 1/2 rho(sum_k r_k^2) (rho = identity without a loss), so
/// H = J^T J, b = J^T r, c = r^T r are the quantities the solver needs. A block must be able to
/// evaluate any subset of its rows; that one capability makes every block compressible.
///
/// Jacobians are with respect to the tangent spaces of the variables (right perturbation,
/// see manifold.hpp). A block may factor its Jacobian through a lower-dimensional quantity:
/// J = J_r A with J_r (N x r) per row and A (r x D) fixed at the evaluation point. Binary
/// registration blocks do this with r = 6 (the relative pose); all rows then share A.

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <span>
#include <string>

namespace carat {

class LossFunction;
class Manifold;

/// Pointers to the ambient storage of a block's variables, in the block's variable order.
using ParameterPointers = std::span<const double* const>;

/// A sum of squared scalar residual rows over a fixed list of variables.
class ResidualBlock {
 public:
  virtual ~ResidualBlock() = default;

  /// Number of scalar residual rows N (>= 1).
  virtual int num_rows() const = 0;

  /// Tangent dimension of each variable, in the order parameters are passed.
  virtual std::span<const int> tangent_dims() const = 0;

  /// Total tangent dimension D (sum of tangent_dims()).
  int tangent_dim() const;

  /// Width r of the Jacobian rows that evaluate_rows() writes; D unless the block is reduced.
  virtual int reduced_dim() const { return tangent_dim(); }

  /// Writes A (r x D, row-major) such that J = J_r A at `params`; the default is the identity.
  virtual void reduced_map(ParameterPointers params, double* A) const;

  /// Evaluates the rows `rows` (indices in [0, N), any order, repeats allowed): residuals[k]
  /// is row rows[k]; when jacobian is not null its row k (r doubles, row-major, stride r) is
  /// the reduced Jacobian of that row.
  virtual void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                             double* jacobian) const = 0;

  /// Adds J_r^T J_r to H_r (r x r) and J_r^T r to b_r over all rows; returns r^T r.
  /// The default evaluates rows in chunks; blocks override it with a faster direct path.
  virtual double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                            Eigen::Ref<Eigen::VectorXd> b_r) const;

  /// The manifold whose tangent the Jacobian columns of variable i are taken in, where the block
  /// fixes one (an autodiff or numeric-difference block: its manifolds argument, or the default
  /// for the variable's sizes); null (the default): the variable's own. Problem::
  /// add_residual_block() refuses a variable that steps on another manifold.
  virtual const Manifold* jacobian_manifold(int /*i*/) const { return nullptr; }

  /// r^T r over all rows (the default evaluates residuals in chunks).
  virtual double squared_norm(ParameterPointers params) const;

  /// A block that holds only the data of `rows` (row k of the result is row rows[k] here), or
  /// null when the block cannot do that; compression uses it to release unused data.
  virtual std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const;

  /// Like extract_rows(), with row k of the result scaled by sqrt(weights[k]) (weights finite
  /// and > 0, one per row) inside its own data, so that no weight needs storing beside it; null
  /// when the block cannot do that or it would not save memory (the default).
  virtual std::unique_ptr<ResidualBlock> extract_weighted_rows(
      std::span<const int> rows, std::span<const double> weights) const;

  /// Bytes of per-row data this block holds (what compression is meant to shrink).
  virtual std::size_t memory_bytes() const = 0;

  /// The block's name for messages ("" when it has none; blocks built from functors take one).
  virtual const std::string& name() const;

  /// The robust loss this block applies to each group of its rows, or null (the default). Such
  /// a block returns its rows weighted by sqrt(rho'(s_g)) at the evaluation point, and its
  /// accumulate() and squared_norm() return c = sum_g rho(s_g) (grouped_rows_block.hpp).
  virtual const LossFunction* group_loss() const { return nullptr; }

  /// For a block with a group loss: the rows `rows` without the loss (row k of the result is the
  /// plain row rows[k]), and in loss_weights[k] (one per row) the weight rho'(s_g) that row's
  /// group has at `params`; compression freezes those weights into the compressed rows. Null
  /// for blocks without a group loss (the default).
  virtual std::unique_ptr<ResidualBlock> extract_rows_without_loss(ParameterPointers params,
                                                                   std::span<const int> rows,
                                                                   double* loss_weights) const;

  /// A constant added to the block's cost beyond its rows (0 by default): accumulate() and
  /// squared_norm() include it. Compressed rows of a robust block carry sum_g rho(s_g) -
  /// sum_g rho'(s_g) s_g here, so that their c is the robust block's.
  virtual double constant_cost() const { return 0.0; }

  /// The block's whole cost function in fewer rows, exact at every value of its variables (not
  /// only at `params`, which may condition its numbers), or null when the block has none (the
  /// default). Registration blocks return their lossless rows (lossless_block.hpp);
  /// solve_recompressed()'s sampled start uses such a form instead of a sample of rows, calling
  /// this from several threads at once (on one object too, when blocks are shared); a
  /// carat::Error from it leaves the block to sampling, any other exception fails the solve. The
  /// form carries no group loss; a block with one returns null.
  virtual std::shared_ptr<const ResidualBlock> exact_form(ParameterPointers params) const;

 protected:
  /// Throws carat::Error ("<who>: ...") unless there is one weight per row and every weight is
  /// finite and > 0 (for extract_weighted_rows() and blocks of weighted rows).
  static void check_row_weights(const char* who, std::span<const int> rows,
                                std::span<const double> weights);
};

/// block.evaluate_rows() through scratch with room for every row of the block, checked: a block
/// that writes past the rows it was asked for, or leaves one of them unwritten, throws
/// carat::Error naming the block instead of corrupting its caller's memory. carat calls
/// user blocks' rows this way wherever it asks for a subset (the default accumulate() and
/// squared_norm(), compressed rows of a block that cannot extract them, error reports).
void evaluate_rows_checked(const ResidualBlock& block, ParameterPointers params,
                           std::span<const int> rows, double* residuals, double* jacobian);

}  // namespace carat
