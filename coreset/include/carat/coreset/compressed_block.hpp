#pragma once

/// A residual block made of weighted rows of another block: row k is sqrt(w_k) times row
/// rows[k] of the inner block, at whatever point it is evaluated. Its quadratic model at the
/// point it was built for equals the inner block's (exact coreset) or estimates it (random).

#include <memory>
#include <span>
#include <vector>

#include "carat/solver/residual_block.hpp"

namespace carat {

/// Selected, weighted rows of an inner residual block.
class CompressedBlock final : public ResidualBlock {
 public:
  /// `inner` provides the rows; `rows` (indices into inner) and `weights` (> 0) are parallel.
  /// Throws carat::Error for mismatched lengths, indices out of range or non-positive weights.
  CompressedBlock(std::shared_ptr<const ResidualBlock> inner, std::vector<int> rows,
                  std::vector<double> weights);

  int num_rows() const override { return static_cast<int>(rows_.size()); }
  std::span<const int> tangent_dims() const override { return inner_->tangent_dims(); }
  int reduced_dim() const override { return inner_->reduced_dim(); }
  void reduced_map(ParameterPointers params, double* A) const override {
    inner_->reduced_map(params, A);
  }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override;
  std::size_t memory_bytes() const override;

  /// The block the rows come from (possibly a smaller extract of the original).
  const ResidualBlock& inner() const { return *inner_; }
  /// Row indices into inner().
  std::span<const int> selected_rows() const { return rows_; }
  /// Weight of each selected row.
  std::span<const double> weights() const { return weights_; }

 private:
  std::shared_ptr<const ResidualBlock> inner_;
  std::vector<int> rows_;
  std::vector<double> weights_;  // square roots taken per evaluation: cheaper than their memory
};

}  // namespace carat
