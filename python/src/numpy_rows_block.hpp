#pragma once

/// A residual block of rows a user's numpy function evaluates (numpy_rows.hpp): a set of rows of
/// one add_rows() call over one tuple of variables. Any subset of its rows can be evaluated (the
/// function is asked for the whole groups they belong to, in one call), so it compresses; an
/// extract keeps only the row indices. With a group loss, its rows come weighted by
/// sqrt(rho'(s_g)) and its cost is sum_g rho(s_g) (as GroupedRowsBlock::with_group_loss()), so
/// that an exact coreset reproduces the robust H, b and c.

#include <Eigen/Core>
#include <array>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "carat/solver/residual_block.hpp"
#include "numpy_rows.hpp"

namespace carat::python {

/// Rows of a NumpyRows over one tuple of its variables.
class NumpyRowsBlock final : public ResidualBlock {
 public:
  /// Rows of `rows` over `variables` (the batch's variable of each slot): every row of a
  /// single-block batch when `groups` and `batch_rows` are empty, else the whole groups `groups`
  /// (ascending) when `batch_rows` is empty, else the batch rows `batch_rows`; with the batch's
  /// group loss when `with_loss`.
  NumpyRowsBlock(std::shared_ptr<const NumpyRows> rows, std::vector<int> variables,
                 std::vector<int> groups, std::vector<int> batch_rows, bool with_loss = true);
  NumpyRowsBlock(const NumpyRowsBlock&) = delete;
  NumpyRowsBlock& operator=(const NumpyRowsBlock&) = delete;
  ~NumpyRowsBlock() override;

  int num_rows() const override;
  std::span<const int> tangent_dims() const override { return rows_->tangent_dims(); }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override;
  double squared_norm(ParameterPointers params) const override;
  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override;
  std::size_t memory_bytes() const override;
  const std::string& name() const override { return rows_->name(); }
  const LossFunction* group_loss() const override;
  std::unique_ptr<ResidualBlock> extract_rows_without_loss(ParameterPointers params,
                                                           std::span<const int> rows,
                                                           double* loss_weights) const override;

 private:
  /// An evaluation and where each asked row lies in it (null position: row k at k). The
  /// positions live in per-thread scratch, valid until the thread's next evaluation.
  struct Evaluated {
    std::shared_ptr<const RowsEvaluation> evaluation;
    const std::size_t* position = nullptr;
    std::size_t at(std::size_t k) const { return position ? position[k] : k; }
  };
  /// Evaluates `rows` (every row, in order, when empty).
  Evaluated evaluate(ParameterPointers params, std::optional<std::span<const int>> rows,
                     bool jacobians) const;
  bool weighted() const { return with_loss_ && rows_->group_loss() != nullptr; }
  /// The batch rows of `rows` (range-checked) into *out.
  void map_rows(std::span<const int> rows, std::vector<int>* out) const;
  /// Whether `rows` are rows of a block of one group (one_group_), each within it.
  bool within_group(std::span<const int> rows) const;

  std::shared_ptr<const NumpyRows> rows_;
  std::vector<int> variables_;
  std::vector<int> groups_;      // the batch groups the rows belong to, ascending
  std::vector<int> batch_rows_;  // block row -> batch row; empty: groups_' rows in order (or
                                 // every row of the batch when groups_ is empty too)
  /// Where the variables lie among the batch's kept values (one_group_ blocks).
  std::span<const NumpyRows::HeldSlot> held_slots() const {
    return many_held_.empty() ? std::span<const NumpyRows::HeldSlot>(held_.data(), num_held_)
                              : std::span<const NumpyRows::HeldSlot>(many_held_);
  }

  bool with_loss_ = true;
  bool one_group_ = false;  // one whole group of a batch of several blocks (an observation)
  int group_ = -1;          // that group (one_group_)
  // held_slots(): in the block for a few variables (read once per block and pass), else in
  // many_held_.
  static constexpr std::size_t kInlineSlots = 4;
  std::array<NumpyRows::HeldSlot, kInlineSlots> held_{};
  std::size_t num_held_ = 0;
  std::vector<NumpyRows::HeldSlot> many_held_;
};

}  // namespace carat::python
