#pragma once

/// Rows that come in groups of a fixed size, one group per datum (a point gives 3 rows, a
/// measurement 1, an image observation 2): the shared machinery of the blocks carat builds from
/// a user's functor (AutoDiffBlock, NumericDiffBlock, RelativePoseAutoDiffBlock). It maps any
/// subset of rows, in any order with repeats, onto whole-group evaluations (each group evaluated
/// once per call for consecutive rows), and extracts the data of selected rows so that a
/// compressed block keeps only those data.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// A residual block of kGroupRows rows per datum of type Data. Derived classes implement
/// prepare() (per-call work on the variables) and evaluate_group().
template <typename Data, int kGroupRows>
class GroupedRowsBlock : public ResidualBlock {
  static_assert(kGroupRows >= 1, "a group has at least one row");

 public:
  /// Rows of a group.
  static constexpr int kRowsPerGroup = kGroupRows;

  int num_rows() const override {
    return row_map_.empty() ? static_cast<int>(data_->size()) * kGroupRows
                            : static_cast<int>(row_map_.size());
  }
  std::span<const int> tangent_dims() const override { return dims_; }

  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    const int r = reduced_dim();
    auto context = prepare(params);
    std::array<double, kGroupRows> values{};
    std::vector<double> group_jacobian(jacobian ? static_cast<std::size_t>(kGroupRows * r) : 0);
    std::int64_t cached = -1;
    const int n = num_rows();
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const int row = rows[k];
      if (row < 0 || row >= n) {
        throw Error(name_ + ": row " + std::to_string(row) + " is out of range (the block has " +
                    std::to_string(n) + " rows)");
      }
      const std::uint32_t slot = row_map_.empty() ? static_cast<std::uint32_t>(row)
                                                  : row_map_[static_cast<std::size_t>(row)];
      const std::int64_t group = slot / kGroupRows;
      const int component = static_cast<int>(slot % kGroupRows);
      // A whole group asked in order (as every full evaluation asks): written in place.
      if (component == 0 && row_map_.empty() && k + kGroupRows <= rows.size() &&
          rows[k + kGroupRows - 1] == row + kGroupRows - 1 &&
          (kGroupRows < 3 || rows[k + 1] == row + 1)) {
        bool whole = true;
        for (int c = 1; c < kGroupRows - 1 && whole; ++c) whole = rows[k + c] == row + c;
        if (whole) {
          double* J = jacobian ? jacobian + k * static_cast<std::size_t>(r) : nullptr;
          if (!evaluate_group(*context, (*data_)[static_cast<std::size_t>(group)], residuals + k,
                              J)) {
            std::fill_n(residuals + k, kGroupRows, std::numeric_limits<double>::quiet_NaN());
            if (J) std::fill_n(J, kGroupRows * r, std::numeric_limits<double>::quiet_NaN());
          }
          k += kGroupRows - 1;
          continue;
        }
      }
      if (group != cached) {
        const bool ok = evaluate_group(*context, (*data_)[static_cast<std::size_t>(group)],
                                       values.data(), jacobian ? group_jacobian.data() : nullptr);
        if (!ok) {  // the functor refused: the rows are not numbers (a step there is rejected)
          values.fill(std::numeric_limits<double>::quiet_NaN());
          std::fill(group_jacobian.begin(), group_jacobian.end(),
                    std::numeric_limits<double>::quiet_NaN());
        }
        cached = group;
      }
      residuals[k] = values[static_cast<std::size_t>(component)];
      if (jacobian) {
        std::copy_n(group_jacobian.data() + component * r, r,
                    jacobian + k * static_cast<std::size_t>(r));
      }
    }
  }

  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override {
    auto data = std::make_shared<std::vector<Data>>();
    std::vector<std::uint32_t> map;
    map.reserve(rows.size());
    std::unordered_map<std::uint32_t, std::uint32_t> local;  // source group -> local group
    const int n = num_rows();
    for (int row : rows) {
      if (row < 0 || row >= n) {
        throw Error(name_ + ": row " + std::to_string(row) + " is out of range (the block has " +
                    std::to_string(n) + " rows)");
      }
      const std::uint32_t slot = row_map_.empty() ? static_cast<std::uint32_t>(row)
                                                  : row_map_[static_cast<std::size_t>(row)];
      const std::uint32_t group = slot / kGroupRows;
      const auto [it, inserted] = local.emplace(group, static_cast<std::uint32_t>(data->size()));
      if (inserted) data->push_back((*data_)[group]);
      const std::uint32_t index = it->second;
      map.push_back(index * kGroupRows + slot % kGroupRows);
    }
    return clone_with(std::move(data), std::move(map));
  }

  std::size_t memory_bytes() const override {
    return data_->size() * sizeof(Data) + row_map_.size() * sizeof(std::uint32_t);
  }

  /// The data, one per group.
  std::span<const Data> data() const { return *data_; }
  /// The name used in messages.
  const std::string& name() const { return name_; }

 protected:
  /// Per-call state that evaluate_group() reads (e.g. the variables as dual numbers).
  struct Context {
    virtual ~Context() = default;
  };

  /// accumulate() for a reduced dimension R known at compile time: each group is evaluated once
  /// and added to fixed-size sums, without staging rows (the default accumulate() copies them
  /// in chunks). Blocks that hold an extract (a row map) use the default.
  template <int R>
  double accumulate_groups(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                           Eigen::Ref<Eigen::VectorXd> b_r) const {
    if (!row_map_.empty()) return ResidualBlock::accumulate(params, H_r, b_r);
    auto context = prepare(params);
    Eigen::Matrix<double, R, R> H = Eigen::Matrix<double, R, R>::Zero();
    Eigen::Matrix<double, R, 1> b = Eigen::Matrix<double, R, 1>::Zero();
    double c = 0.0;
    Eigen::Matrix<double, kGroupRows, 1> e;
    Eigen::Matrix<double, kGroupRows, R, Eigen::RowMajor> J;
    for (const Data& datum : *data_) {
      if (!evaluate_group(*context, datum, e.data(), J.data())) {
        e.setConstant(std::numeric_limits<double>::quiet_NaN());
        J.setConstant(std::numeric_limits<double>::quiet_NaN());
      }
      H.noalias() += J.transpose() * J;
      b.noalias() += J.transpose() * e;
      c += e.squaredNorm();
    }
    H_r += H;
    b_r += b;
    return c;
  }

  GroupedRowsBlock(std::shared_ptr<const std::vector<Data>> data, std::vector<int> tangent_dims,
                   std::string name, std::vector<std::uint32_t> row_map = {})
      : data_(std::move(data)),
        dims_(std::move(tangent_dims)),
        name_(std::move(name)),
        row_map_(std::move(row_map)) {
    if (!data_ || data_->empty())
      throw Error(name_ + ": no data (a block needs at least one group)");
    if (static_cast<double>(data_->size()) * kGroupRows > 2147483647.0) {
      throw Error(name_ + ": " + std::to_string(data_->size()) + " groups of " +
                  std::to_string(kGroupRows) + " rows are more rows than an int can index");
    }
  }

  /// Work done once per call on the variables' values.
  virtual std::unique_ptr<Context> prepare(ParameterPointers params) const = 0;
  /// Writes the group's kGroupRows residuals and, when jacobian is not null, their reduced
  /// Jacobian rows (row-major, reduced_dim() columns). False: the functor refused the values.
  virtual bool evaluate_group(const Context& context, const Data& datum, double* residuals,
                              double* jacobian) const = 0;
  /// The same block over other data and row map (for extract_rows()).
  virtual std::unique_ptr<ResidualBlock> clone_with(std::shared_ptr<const std::vector<Data>> data,
                                                    std::vector<std::uint32_t> row_map) const = 0;

  std::shared_ptr<const std::vector<Data>> data_;
  std::vector<int> dims_;
  std::string name_;
  std::vector<std::uint32_t> row_map_;  // empty: row r is component r % G of group r / G
};

}  // namespace carat
