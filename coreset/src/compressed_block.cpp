#include "carat/coreset/compressed_block.hpp"

#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

CompressedBlock::CompressedBlock(std::shared_ptr<const ResidualBlock> inner, std::vector<int> rows,
                                 std::vector<double> weights, double constant_cost)
    : inner_(std::move(inner)),
      rows_(std::move(rows)),
      weights_(std::move(weights)),
      constant_cost_(constant_cost) {
  if (!inner_) throw Error("CompressedBlock: inner block is null");
  if (!std::isfinite(constant_cost_)) {
    throw Error("CompressedBlock: the constant cost " + std::to_string(constant_cost_) +
                " is not finite");
  }
  check_row_weights("CompressedBlock", rows_, weights_);
  if (rows_.empty()) throw Error("CompressedBlock: no rows selected");
  const int n = inner_->num_rows();
  for (std::size_t k = 0; k < rows_.size(); ++k) {
    if (rows_[k] < 0 || rows_[k] >= n) {
      throw Error("CompressedBlock: row " + std::to_string(rows_[k]) +
                  " is out of range (block has " + std::to_string(n) + " rows)");
    }
  }
}

CompressedBlock::CompressedBlock(std::shared_ptr<const ResidualBlock> weighted_rows)
    : inner_(std::move(weighted_rows)) {
  if (!inner_) throw Error("CompressedBlock: inner block is null");
  if (inner_->num_rows() < 1) throw Error("CompressedBlock: no rows selected");
}

void CompressedBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                    double* residuals, double* jacobian) const {
  if (folded()) {
    inner_->evaluate_rows(params, rows, residuals, jacobian);
    return;
  }
  std::vector<int> inner_rows(rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    if (rows[k] < 0 || static_cast<std::size_t>(rows[k]) >= rows_.size()) {
      throw Error("CompressedBlock: row " + std::to_string(rows[k]) +
                  " is out of range (the block has " + std::to_string(rows_.size()) + " rows)");
    }
    inner_rows[k] = rows_[static_cast<std::size_t>(rows[k])];
  }
  evaluate_rows_checked(*inner_, params, inner_rows, residuals, jacobian);
  const auto r = static_cast<std::size_t>(inner_->reduced_dim());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const double s = std::sqrt(weights_[static_cast<std::size_t>(rows[k])]);
    residuals[k] *= s;
    if (jacobian) {
      for (std::size_t c = 0; c < r; ++c) jacobian[k * r + c] *= s;
    }
  }
}

namespace {

/// Largest scratch (bytes) for evaluating every kept row in one call of the inner block.
constexpr std::size_t kOneCallBytes = std::size_t{16} << 20;

}  // namespace

bool CompressedBlock::in_one_call(bool with_jacobian) const {
  const std::size_t doubles =
      with_jacobian ? static_cast<std::size_t>(inner_->reduced_dim()) + 1 : 1;
  return rows_.size() * doubles * sizeof(double) <= kOneCallBytes;
}

double CompressedBlock::accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                                   Eigen::Ref<Eigen::VectorXd> b_r) const {
  // Folded: the inner block's rows are the rows, and its own (possibly fused) accumulate() sums
  // them.
  if (folded()) return inner_->accumulate(params, H_r, b_r) + constant_cost_;
  if (!in_one_call(true)) return ResidualBlock::accumulate(params, H_r, b_r);
  // Every kept row in one call of the inner block (a block that calls out per evaluation, such
  // as a Python function's, is called once rather than per chunk of rows).
  const auto n = static_cast<Eigen::Index>(rows_.size());
  std::vector<int> all(rows_.size());
  std::iota(all.begin(), all.end(), 0);
  Eigen::VectorXd e(n);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(n, reduced_dim());
  evaluate_rows(params, all, e.data(), J.data());
  H_r.selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
  H_r.triangularView<Eigen::StrictlyUpper>() = H_r.transpose();
  b_r.noalias() += J.transpose() * e;
  return constant_cost_ + e.squaredNorm();
}

double CompressedBlock::squared_norm(ParameterPointers params) const {
  if (folded()) return inner_->squared_norm(params) + constant_cost_;
  if (!in_one_call(false)) return ResidualBlock::squared_norm(params);
  std::vector<int> all(rows_.size());
  std::iota(all.begin(), all.end(), 0);
  Eigen::VectorXd e(static_cast<Eigen::Index>(rows_.size()));
  evaluate_rows(params, all, e.data(), nullptr);
  return constant_cost_ + e.squaredNorm();
}

std::unique_ptr<ResidualBlock> CompressedBlock::extract_rows(std::span<const int> rows) const {
  if (folded()) {
    std::unique_ptr<ResidualBlock> part = inner_->extract_rows(rows);
    if (!part) return nullptr;
    return std::make_unique<CompressedBlock>(std::shared_ptr<const ResidualBlock>(std::move(part)));
  }
  std::vector<int> inner_rows;
  std::vector<double> weights;
  for (int k : rows) {
    inner_rows.push_back(rows_[static_cast<std::size_t>(k)]);
    weights.push_back(weights_[static_cast<std::size_t>(k)]);
  }
  return std::make_unique<CompressedBlock>(inner_, std::move(inner_rows), std::move(weights));
}

std::size_t CompressedBlock::memory_bytes() const {
  return inner_->memory_bytes() + rows_.size() * sizeof(int) + weights_.size() * sizeof(double);
}

}  // namespace carat
