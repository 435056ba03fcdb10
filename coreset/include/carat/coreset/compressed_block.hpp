#pragma once

/// A residual block made of weighted rows of another block: row k is sqrt(w_k) times row
/// rows[k] of the inner block, at whatever point it is evaluated. Its quadratic model at the
/// point it was built for equals the inner block's (exact coreset) or estimates it (random).
/// When the inner block could fold the weights into its own rows (extract_weighted_rows), the
/// rows and weights are not kept a second time: the inner block's rows are the rows. Rows of a
/// block that cannot extract them are read from the whole inner block through
/// evaluate_rows_checked(), so a block that breaks the row contract is an error, not a write past
/// a buffer.

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "carat/solver/residual_block.hpp"

namespace carat {

/// Selected, weighted rows of an inner residual block.
class CompressedBlock final : public ResidualBlock {
 public:
  /// `inner` provides the rows; `rows` (indices into inner) and `weights` (> 0) are parallel;
  /// `constant_cost` (finite) is added to the block's cost (see ResidualBlock::constant_cost()).
  /// Throws carat::Error for mismatched lengths, indices out of range, non-positive weights or a
  /// constant that is not finite.
  CompressedBlock(std::shared_ptr<const ResidualBlock> inner, std::vector<int> rows,
                  std::vector<double> weights, double constant_cost = 0.0);
  /// Every row of `weighted_rows`, whose weights are already inside its rows. Throws
  /// carat::Error if it is null or has no rows.
  explicit CompressedBlock(std::shared_ptr<const ResidualBlock> weighted_rows);

  int num_rows() const override {
    return folded() ? inner_->num_rows() : static_cast<int>(rows_.size());
  }
  std::span<const int> tangent_dims() const override { return inner_->tangent_dims(); }
  int reduced_dim() const override { return inner_->reduced_dim(); }
  void reduced_map(ParameterPointers params, double* A) const override {
    inner_->reduced_map(params, A);
  }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override;
  double squared_norm(ParameterPointers params) const override;
  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override;
  std::size_t memory_bytes() const override;
  const std::string& name() const override { return inner_->name(); }
  double constant_cost() const override { return constant_cost_; }

  /// The block the rows come from (possibly a smaller extract of the original).
  const ResidualBlock& inner() const { return *inner_; }
  /// True when the weights live inside inner()'s rows (then every row of inner() is a row here,
  /// and selected_rows() and weights() are empty).
  bool folded() const { return rows_.empty(); }
  /// Row indices into inner() (empty when folded()).
  std::span<const int> selected_rows() const { return rows_; }
  /// Weight of each selected row (empty when folded()).
  std::span<const double> weights() const { return weights_; }

 private:
  /// Whether every kept row is evaluated in one call of the inner block (scratch small enough).
  bool in_one_call(bool with_jacobian) const;

  std::shared_ptr<const ResidualBlock> inner_;
  std::vector<int> rows_;
  std::vector<double> weights_;  // square roots taken per evaluation: cheaper than their memory
  double constant_cost_ = 0.0;
};

}  // namespace carat
