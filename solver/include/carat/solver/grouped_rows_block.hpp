#pragma once

/// Rows that come in groups of a fixed size, one group per datum (a point gives 3 rows, a
/// measurement 1, an image observation 2): the shared machinery of the blocks carat builds from
/// a user's functor (AutoDiffBlock, NumericDiffBlock, RelativePoseAutoDiffBlock). It maps any
/// subset of rows, in any order with repeats, onto whole-group evaluations (each group evaluated
/// once per call for consecutive rows), and extracts the data of selected rows so that a
/// compressed block keeps only those data.
///
/// **A robust loss per group** (with_group_loss()): each group g (each observation) is weighted
/// by its own rho(s_g), s_g = |r_g|^2, as Ceres's per-residual-block loss, and the block still
/// compresses. At the evaluation point every row of g is scaled by sqrt(rho'(s_g)) (iteratively
/// reweighted least squares): evaluate_rows() returns those rows, accumulate() returns
/// H = sum_g rho'(s_g) J_g^T J_g, b = sum_g rho'(s_g) J_g^T r_g (the exact gradient of
/// 1/2 sum_g rho(s_g)) and c = sum_g rho(s_g), and squared_norm() the same c. The second-order
/// term 2 rho''(s_g) J_g^T r_g r_g^T J_g is dropped: for losses with rho'' <= 0 (Huber, Cauchy and
/// every robust loss) this is what Ceres's corrector does as well, and it keeps H positive
/// semi-definite; the optimum is unchanged since the gradient is exact. Because the weights are
/// per row, an exact coreset of the weighted rows reproduces the robust H, b and c (compress()
/// freezes the weights into the compressed rows).

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// A residual block of kGroupRows rows per datum of type Data. Derived classes implement
/// prepare() (per-call work on the variables) and evaluate_group(); they may instead override
/// evaluate_rows(), accumulate() and squared_norm() with the walk_rows(), accumulate_rows() and
/// sum_rows() templates, which take the group evaluation as a callable (no per-call allocation).
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
    auto context = prepare(params);
    walk_rows<Eigen::Dynamic>(rows, residuals, jacobian, nullptr,
                              [&](const Data& datum, double* e, double* J) {
                                return evaluate_group(*context, datum, e, J);
                              });
  }

  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override {
    auto context = prepare(params);
    return accumulate_rows<Eigen::Dynamic>(H_r, b_r, [&](const Data& datum, double* e, double* J) {
      return evaluate_group(*context, datum, e, J);
    });
  }

  double squared_norm(ParameterPointers params) const override {
    auto context = prepare(params);
    return sum_rows(
        [&](const Data& datum, double* e) { return evaluate_group(*context, datum, e, nullptr); });
  }

  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override {
    std::unique_ptr<ResidualBlock> out = extract_plain(rows);
    static_cast<GroupedRowsBlock&>(*out).group_loss_ = group_loss_;
    return out;
  }

  const LossFunction* group_loss() const override { return group_loss_.get(); }

  std::unique_ptr<ResidualBlock> extract_rows_without_loss(ParameterPointers params,
                                                           std::span<const int> rows,
                                                           double* loss_weights) const override {
    if (!group_loss_) return nullptr;
    auto context = prepare(params);
    const int n = num_rows();
    std::array<double, kGroupRows> e{};
    std::int64_t cached = -1;
    double weight = 1.0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto [group, component] = locate(rows[k], n);
      (void)component;
      if (group != cached) {
        const bool ok =
            evaluate_group(*context, (*data_)[static_cast<std::size_t>(group)], e.data(), nullptr);
        weight = ok ? loss_weights_of(e.data()).rho1 : std::numeric_limits<double>::quiet_NaN();
        cached = group;
      }
      loss_weights[k] = weight;
    }
    return extract_plain(rows);
  }

  /// This block with a robust loss applied to each group of rows (see the file comment); the
  /// data are shared, not copied. Throws carat::Error for a null loss.
  std::shared_ptr<ResidualBlock> with_group_loss(std::shared_ptr<const LossFunction> loss) const {
    if (!loss) throw Error(name_ + ": with_group_loss() needs a loss (got null)");
    std::unique_ptr<ResidualBlock> out = clone_with(data_, row_map_);
    static_cast<GroupedRowsBlock&>(*out).group_loss_ = std::move(loss);
    return std::shared_ptr<ResidualBlock>(std::move(out));
  }

  std::size_t memory_bytes() const override {
    return data_->size() * sizeof(Data) + row_map_.size() * sizeof(std::uint32_t);
  }

  /// The data, one per group.
  std::span<const Data> data() const { return *data_; }
  const std::string& name() const override { return name_; }

 protected:
  /// Per-call state that evaluate_group() reads (e.g. the variables as dual numbers).
  struct Context {
    virtual ~Context() = default;
  };

  /// Evaluates `rows` through `eval(datum, residuals, jacobian)`, which writes one group's
  /// kGroupRows residuals and, when jacobian is not null, their R (or reduced_dim() when R is
  /// Eigen::Dynamic) Jacobian columns row-major, and returns false when the functor refused.
  /// Refused groups become NaN rows; the group loss, if any, weights each group. With row_cost
  /// not null, row_cost[k] is row k's share of the block's cost (its squared residual without a
  /// loss; rho(s_g) r_k^2 / s_g of its group with one, so that a group's shares add to rho(s_g)).
  template <int R, typename Eval>
  void walk_rows(std::span<const int> rows, double* residuals, double* jacobian, double* row_cost,
                 Eval&& eval) const {
    const int r = R == Eigen::Dynamic ? reduced_dim() : R;
    std::array<double, kGroupRows> values{}, shares{};
    constexpr std::size_t kStack = R == Eigen::Dynamic ? 64 * kGroupRows : R * kGroupRows;
    std::array<double, kStack> stack_jacobian;
    std::vector<double> heap_jacobian;
    double* group_jacobian = stack_jacobian.data();
    if (jacobian && static_cast<std::size_t>(kGroupRows * r) > kStack) {
      heap_jacobian.resize(static_cast<std::size_t>(kGroupRows * r));
      group_jacobian = heap_jacobian.data();
    }
    std::int64_t cached = -1;
    const int n = num_rows();
    if (whole_groups_in_order(rows, n)) {  // every full evaluation: no per-row bookkeeping
      const std::int64_t first = rows[0] / kGroupRows;
      const auto groups = static_cast<std::int64_t>(rows.size() / kGroupRows);
      for (std::int64_t g = 0; g < groups; ++g) {
        const std::size_t k = static_cast<std::size_t>(g) * kGroupRows;
        evaluate_weighted(eval, first + g, residuals + k,
                          jacobian ? jacobian + k * static_cast<std::size_t>(r) : nullptr, r,
                          row_cost ? row_cost + k : nullptr);
      }
      return;
    }
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const int row = rows[k];
      const auto [group, component] = locate(row, n);
      // A whole group asked in order (as every full evaluation asks): written in place.
      if (component == 0 && row_map_.empty() && k + kGroupRows <= rows.size() &&
          whole_group_at(rows, k)) {
        double* J = jacobian ? jacobian + k * static_cast<std::size_t>(r) : nullptr;
        evaluate_weighted(eval, group, residuals + k, J, r, row_cost ? row_cost + k : nullptr);
        k += kGroupRows - 1;
        continue;
      }
      if (group != cached) {
        evaluate_weighted(eval, group, values.data(), jacobian ? group_jacobian : nullptr, r,
                          shares.data());
        cached = group;
      }
      residuals[k] = values[static_cast<std::size_t>(component)];
      if (row_cost) row_cost[k] = shares[static_cast<std::size_t>(component)];
      if (jacobian) {
        std::copy_n(group_jacobian + component * r, r, jacobian + k * static_cast<std::size_t>(r));
      }
    }
  }

  /// accumulate() through `eval` (as walk_rows()): every group evaluated once, its (weighted)
  /// rows added to H_r and b_r in batches; returns c (sum_g rho(s_g) with a group loss).
  template <int R, typename Eval>
  double accumulate_rows(Eigen::Ref<Eigen::MatrixXd> H_r, Eigen::Ref<Eigen::VectorXd> b_r,
                         Eval&& eval) const {
    const int r = R == Eigen::Dynamic ? reduced_dim() : R;
    constexpr int kBatchGroups = std::max(1, 64 / kGroupRows);
    constexpr int kBatchRows = kBatchGroups * kGroupRows;
    using Rows = Eigen::Matrix<double, kBatchRows, R, R == 1 ? Eigen::ColMajor : Eigen::RowMajor>;
    Rows J(kBatchRows, r);
    Eigen::Matrix<double, kBatchRows, 1> e;
    Eigen::Matrix<double, R, R> H = Eigen::Matrix<double, R, R>::Zero(r, r);
    Eigen::Matrix<double, R, 1> b = Eigen::Matrix<double, R, 1>::Zero(r);
    double c = 0.0;
    const auto flush = [&](int used) {
      if constexpr (R == 1) {
        for (int i = 0; i < used; ++i) {
          H(0, 0) += J(i, 0) * J(i, 0);
          b[0] += J(i, 0) * e[i];
        }
      } else if constexpr (R != Eigen::Dynamic && R <= 4) {
        // A few columns: the lower triangle's sums in registers beat a packed rank-k update.
        std::array<double, R*(R + 1) / 2> h{};
        std::array<double, R> g{};
        const double* rows = J.data();
        for (int i = 0; i < used; ++i, rows += R) {
          int slot = 0;
          for (int j = 0; j < R; ++j) {
            g[static_cast<std::size_t>(j)] += rows[j] * e[i];
            for (int k = j; k < R; ++k) h[static_cast<std::size_t>(slot++)] += rows[j] * rows[k];
          }
        }
        int slot = 0;
        for (int j = 0; j < R; ++j) {
          b[j] += g[static_cast<std::size_t>(j)];
          for (int k = j; k < R; ++k) H(k, j) += h[static_cast<std::size_t>(slot++)];
        }
      } else if constexpr (R != Eigen::Dynamic && R <= 8) {
        // Up to 8 columns: each group's small product, coefficient by coefficient, stays in
        // registers (a packed rank-k update spends more on packing than on these sizes).
        int i = 0;
        for (; i + kGroupRows <= used; i += kGroupRows) {
          const auto Jg = J.template middleRows<kGroupRows>(i);
          H.noalias() += Jg.transpose() * Jg;
          b.noalias() += Jg.transpose() * e.template segment<kGroupRows>(i);
        }
        for (; i < used; ++i) {  // an extract's last rows need not make a whole group
          H.noalias() += J.row(i).transpose() * J.row(i);
          b.noalias() += J.row(i).transpose() * e[i];
        }
      } else if (used == kBatchRows) {
        H.template selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
        b.noalias() += J.transpose() * e;
      } else {
        H.template selfadjointView<Eigen::Lower>().rankUpdate(J.topRows(used).transpose());
        b.noalias() += J.topRows(used).transpose() * e.head(used);
      }
    };
    if (row_map_.empty()) {
      int used = 0;
      std::array<double, kGroupRows> shares{};
      const auto groups = static_cast<std::int64_t>(data_->size());
      for (std::int64_t g = 0; g < groups; ++g) {
        double* eg = e.data() + used;
        evaluate_weighted(eval, g, eg, J.data() + static_cast<std::ptrdiff_t>(used) * r, r,
                          group_loss_ ? shares.data() : nullptr);
        if (group_loss_) {
          for (double s : shares) c += s;
        } else {
          for (int i = 0; i < kGroupRows; ++i) c += eg[i] * eg[i];
        }
        used += kGroupRows;
        if (used == kBatchRows) {
          flush(used);
          used = 0;
        }
      }
      if (used > 0) flush(used);
    } else {
      // An extract: its rows in batches, each row with its share of its group's cost.
      std::array<int, kBatchRows> rows{};
      std::array<double, kBatchRows> shares{};
      const int n = num_rows();
      for (int begin = 0; begin < n; begin += kBatchRows) {
        const int count = std::min(kBatchRows, n - begin);
        for (int k = 0; k < count; ++k) rows[static_cast<std::size_t>(k)] = begin + k;
        walk_rows<R>(std::span<const int>(rows.data(), static_cast<std::size_t>(count)), e.data(),
                     J.data(), shares.data(), eval);
        for (int k = 0; k < count; ++k) c += shares[static_cast<std::size_t>(k)];
        flush(count);
      }
    }
    H.template triangularView<Eigen::StrictlyUpper>() = H.transpose();
    if constexpr (R == 1) {  // (a 1 x 1 sum read as a vector packet would read past it)
      H_r(0, 0) += H(0, 0);
      b_r[0] += b[0];
    } else {
      H_r += H;
      b_r += b;
    }
    return c;
  }

  /// squared_norm() through `eval(datum, residuals)` (no Jacobian): the block's c.
  template <typename Eval>
  double sum_rows(Eval&& eval) const {
    const auto residual_only = [&](const Data& datum, double* e, double* /*J*/) {
      return eval(datum, e);
    };
    double c = 0.0;
    std::array<double, kGroupRows> e{}, shares{};
    if (row_map_.empty()) {
      const auto groups = static_cast<std::int64_t>(data_->size());
      for (std::int64_t g = 0; g < groups; ++g) {
        if (group_loss_) {
          evaluate_weighted(residual_only, g, e.data(), nullptr, 0, shares.data());
          for (double s : shares) c += s;
        } else {
          evaluate_weighted(residual_only, g, e.data(), nullptr, 0, nullptr);
          for (double v : e) c += v * v;
        }
      }
      return c;
    }
    constexpr int kBatchRows = 64;
    std::array<int, kBatchRows> rows{};
    std::array<double, kBatchRows> values{}, row_shares{};
    const int n = num_rows();
    for (int begin = 0; begin < n; begin += kBatchRows) {
      const int count = std::min(kBatchRows, n - begin);
      for (int k = 0; k < count; ++k) rows[static_cast<std::size_t>(k)] = begin + k;
      walk_rows<1>(std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
                   values.data(), nullptr, row_shares.data(), residual_only);
      for (int k = 0; k < count; ++k) c += row_shares[static_cast<std::size_t>(k)];
    }
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
  /// The same block over other data and row map (for extract_rows()), without a group loss.
  virtual std::unique_ptr<ResidualBlock> clone_with(std::shared_ptr<const std::vector<Data>> data,
                                                    std::vector<std::uint32_t> row_map) const = 0;

  std::shared_ptr<const std::vector<Data>> data_;
  std::vector<int> dims_;
  std::string name_;
  std::vector<std::uint32_t> row_map_;  // empty: row r is component r % G of group r / G
  std::shared_ptr<const LossFunction> group_loss_;  // null: plain least squares

 private:
  /// Group and component of `row`; throws for a row out of range.
  std::pair<std::int64_t, int> locate(int row, int n) const {
    if (row < 0 || row >= n) {
      throw Error(name_ + ": row " + std::to_string(row) + " is out of range (the block has " +
                  std::to_string(n) + " rows)");
    }
    const std::uint32_t slot = row_map_.empty() ? static_cast<std::uint32_t>(row)
                                                : row_map_[static_cast<std::size_t>(row)];
    return {static_cast<std::int64_t>(slot / kGroupRows), static_cast<int>(slot % kGroupRows)};
  }

  /// Whether `rows` is a run of consecutive rows of whole groups, in order, in range (no row
  /// map): then walk_rows() evaluates group after group.
  bool whole_groups_in_order(std::span<const int> rows, int n) const {
    if (!row_map_.empty() || rows.empty() || rows.size() % kGroupRows != 0) return false;
    const int first = rows[0];
    if (first < 0 || first % kGroupRows != 0 ||
        static_cast<std::int64_t>(first) + static_cast<std::int64_t>(rows.size()) > n) {
      return false;
    }
    for (std::size_t k = 1; k < rows.size(); ++k) {
      if (rows[k] != first + static_cast<int>(k)) return false;
    }
    return true;
  }

  /// Whether rows[k ..] holds rows[k], rows[k] + 1, ... of one whole group.
  static bool whole_group_at(std::span<const int> rows, std::size_t k) {
    for (int c = 1; c < kGroupRows; ++c) {
      if (rows[k + static_cast<std::size_t>(c)] != rows[k] + c) return false;
    }
    return true;
  }

  /// The loss's value at a group's residuals e (kGroupRows); throws when the loss misbehaves at a
  /// finite s (a NaN s, from a refused group, passes through).
  LossValue loss_weights_of(const double* e) const {
    double s = 0.0;
    for (int i = 0; i < kGroupRows; ++i) s += e[i] * e[i];
    const LossValue value = group_loss_->evaluate(s);
    if (std::isfinite(s) &&
        !(std::isfinite(value.rho) && std::isfinite(value.rho1) && value.rho1 >= 0.0)) {
      throw Error(name_ + ": the group loss '" + group_loss_->name() +
                  "' returned rho = " + std::to_string(value.rho) +
                  ", rho' = " + std::to_string(value.rho1) + " at s = " + std::to_string(s) +
                  "; a loss must return finite values with rho' >= 0");
    }
    return value;
  }

  /// One group through eval, refused groups as NaN, the group loss applied; shares as in
  /// walk_rows().
  template <typename Eval>
  void evaluate_weighted(Eval& eval, std::int64_t group, double* e, double* J, int r,
                         double* shares) const {
    constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    if (!eval((*data_)[static_cast<std::size_t>(group)], e, J)) {
      std::fill_n(e, kGroupRows, kNaN);
      if (J) std::fill_n(J, kGroupRows * r, kNaN);
    }
    if (!group_loss_) {
      if (shares) {
        for (int i = 0; i < kGroupRows; ++i) shares[i] = e[i] * e[i];
      }
      return;
    }
    double s = 0.0;
    for (int i = 0; i < kGroupRows; ++i) s += e[i] * e[i];
    const LossValue value = loss_weights_of(e);
    if (shares) {
      const double per_unit = s > 0.0 ? value.rho / s : value.rho1;
      for (int i = 0; i < kGroupRows; ++i) shares[i] = per_unit * e[i] * e[i];
    }
    const double w = std::sqrt(value.rho1);
    for (int i = 0; i < kGroupRows; ++i) e[i] *= w;
    if (J) {
      for (int i = 0; i < kGroupRows * r; ++i) J[i] *= w;
    }
  }

  /// The rows' data without a group loss (extract_rows() and extract_rows_without_loss()).
  std::unique_ptr<ResidualBlock> extract_plain(std::span<const int> rows) const {
    auto data = std::make_shared<std::vector<Data>>();
    std::vector<std::uint32_t> map;
    map.reserve(rows.size());
    std::unordered_map<std::uint32_t, std::uint32_t> local;  // source group -> local group
    const int n = num_rows();
    for (int row : rows) {
      const auto [group, component] = locate(row, n);
      const auto g = static_cast<std::uint32_t>(group);
      const auto [it, inserted] = local.emplace(g, static_cast<std::uint32_t>(data->size()));
      if (inserted) data->push_back((*data_)[g]);
      map.push_back(it->second * kGroupRows + static_cast<std::uint32_t>(component));
    }
    return clone_with(std::move(data), std::move(map));
  }
};

}  // namespace carat
