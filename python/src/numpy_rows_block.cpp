#include "numpy_rows_block.hpp"

#include <algorithm>
#include <utility>
#include <variant>

#include "carat/base/error.hpp"

namespace carat::python {

namespace {

constexpr int kChunkRows = 128;
/// Rows per step of the products over arrays read in place (about 400 KB of a 2-column block).
constexpr std::size_t kCacheRows = 16384;
/// Columns up to which J_a^T J_b is formed as dot products of whole columns.
constexpr int kDotColumns = 4;

using StridedMatrix =
    Eigen::Map<const Eigen::MatrixXd, 0, Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>>;
/// Columns of contiguous doubles (numpy's J.T of a (t, n) array): vectorized products.
using ColumnsMatrix = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
/// Rows of contiguous doubles (a C-ordered (n, t) array): vectorized products.
using RowsMatrix =
    Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>, 0,
               Eigen::OuterStride<>>;
using AnyMatrix = std::variant<ColumnsMatrix, RowsMatrix, StridedMatrix>;
using StridedVector = Eigen::Map<const Eigen::VectorXd, 0, Eigen::InnerStride<Eigen::Dynamic>>;
using AnyVector = std::variant<Eigen::Map<const Eigen::VectorXd>, StridedVector>;

/// Whether the view is an Eigen map: evenly spaced rows, strides of whole doubles.
bool whole_doubles(const StridedRows& view) {
  return view.group_rows == 1 &&
         view.row_stride() % static_cast<std::ptrdiff_t>(sizeof(double)) == 0 &&
         view.column % static_cast<std::ptrdiff_t>(sizeof(double)) == 0;
}

/// The view (whole_doubles()) as the fastest Eigen map its layout allows.
AnyMatrix matrix_of(const StridedRows& view, std::size_t rows, int columns) {
  constexpr auto kSize = static_cast<std::ptrdiff_t>(sizeof(double));
  const auto* data = reinterpret_cast<const double*>(view.data);
  const auto n = static_cast<Eigen::Index>(rows);
  const std::ptrdiff_t row = view.row_stride() / kSize;
  const std::ptrdiff_t column = view.column / kSize;
  if (row == 1 && (columns == 1 || column >= n)) {
    return ColumnsMatrix(data, n, columns, Eigen::OuterStride<>(columns == 1 ? n : column));
  }
  if ((column == 1 || columns == 1) && row >= columns) {
    return RowsMatrix(data, n, columns, Eigen::OuterStride<>(row));
  }
  return StridedMatrix(data, n, columns,
                       Eigen::Stride<Eigen::Dynamic, Eigen::Dynamic>(column, row));
}

/// The residuals (whole_doubles()) as an Eigen vector, contiguous when they are.
AnyVector vector_of(const StridedRows& view, std::size_t rows) {
  constexpr auto kSize = static_cast<std::ptrdiff_t>(sizeof(double));
  const auto* data = reinterpret_cast<const double*>(view.data);
  const auto n = static_cast<Eigen::Index>(rows);
  if (view.row_stride() == kSize) return Eigen::Map<const Eigen::VectorXd>(data, n);
  return StridedVector(data, n, Eigen::InnerStride<Eigen::Dynamic>(view.row_stride() / kSize));
}

}  // namespace

NumpyRowsBlock::NumpyRowsBlock(std::shared_ptr<const NumpyRows> rows, std::vector<int> variables,
                               std::vector<int> groups, std::vector<int> batch_rows, bool with_loss)
    : rows_(std::move(rows)),
      variables_(std::move(variables)),
      groups_(std::move(groups)),
      batch_rows_(std::move(batch_rows)),
      with_loss_(with_loss) {
  if (!batch_rows_.empty()) {
    const int k = rows_->group_rows();
    groups_.clear();
    for (int row : batch_rows_) {
      if (groups_.empty() || groups_.back() != row / k) groups_.push_back(row / k);
    }
    std::sort(groups_.begin(), groups_.end());
    groups_.erase(std::unique(groups_.begin(), groups_.end()), groups_.end());
  }
  one_group_ = batch_rows_.empty() && groups_.size() == 1 && !rows_->single_block();
  if (one_group_) {
    group_ = groups_.front();
    if (variables_.size() <= kInlineSlots) {
      for (int v : variables_) held_[num_held_++] = rows_->held_slot(v);
    } else {
      for (int v : variables_) many_held_.push_back(rows_->held_slot(v));
    }
  }
  rows_->acquire(groups_);
}

bool NumpyRowsBlock::within_group(std::span<const int> rows) const {
  if (!one_group_) return false;
  const int k = rows_->group_rows();
  for (int row : rows) {
    if (row < 0 || row >= k) return false;
  }
  return true;
}

NumpyRowsBlock::~NumpyRowsBlock() { rows_->release(groups_); }

int NumpyRowsBlock::num_rows() const {
  if (!batch_rows_.empty()) return static_cast<int>(batch_rows_.size());
  return (groups_.empty() ? rows_->num_groups() : static_cast<int>(groups_.size())) *
         rows_->group_rows();
}

const LossFunction* NumpyRowsBlock::group_loss() const {
  return with_loss_ ? rows_->group_loss().get() : nullptr;
}

std::size_t NumpyRowsBlock::memory_bytes() const {
  return (batch_rows_.size() + groups_.size()) * sizeof(int);
}

void NumpyRowsBlock::map_rows(std::span<const int> rows, std::vector<int>* out) const {
  const int n = num_rows();
  out->resize(rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const int row = rows[k];
    if (row < 0 || row >= n) {
      throw Error(rows_->name() + ": row " + std::to_string(row) +
                  " is out of range (the block has " + std::to_string(n) + " rows)");
    }
    if (!batch_rows_.empty()) {
      (*out)[k] = batch_rows_[static_cast<std::size_t>(row)];
    } else if (groups_.empty()) {
      (*out)[k] = row;
    } else {
      const int group_rows = rows_->group_rows();
      (*out)[k] =
          groups_[static_cast<std::size_t>(row / group_rows)] * group_rows + row % group_rows;
    }
  }
}

NumpyRowsBlock::Evaluated NumpyRowsBlock::evaluate(ParameterPointers params,
                                                   std::optional<std::span<const int>> rows,
                                                   bool jacobians) const {
  const int n = num_rows();
  const auto in_order = [&] {
    if (rows->size() != static_cast<std::size_t>(n)) return false;
    for (int k = 0; k < n; ++k) {
      if ((*rows)[static_cast<std::size_t>(k)] != k) return false;
    }
    return true;
  };
  const bool all_rows = !rows || in_order();
  if (batch_rows_.empty() && groups_.empty() && all_rows) {  // the whole batch, in order
    return {rows_->evaluate_all(variables_, params, jacobians), nullptr};
  }
  // Per-thread scratch: small blocks (an observation of two rows) are evaluated by the hundred
  // thousand per pass, and allocations would cost more than reading their rows.
  struct Scratch {
    std::vector<int> all, batch, groups;
    std::vector<std::size_t> start, position;
  };
  thread_local Scratch scratch;
  const auto k_rows = static_cast<std::size_t>(rows_->group_rows());
  if (all_rows && batch_rows_.empty() && !rows_->single_block()) {  // its own whole groups
    Evaluated out;
    out.evaluation = rows_->lookup(variables_, params, groups_, jacobians, &scratch.start);
    scratch.position.resize(static_cast<std::size_t>(n));
    for (std::size_t q = 0; q < groups_.size(); ++q) {
      for (std::size_t c = 0; c < k_rows; ++c)
        scratch.position[q * k_rows + c] = scratch.start[q] + c;
    }
    out.position = scratch.position.data();
    return out;
  }
  if (!rows) {
    scratch.all.resize(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) scratch.all[static_cast<std::size_t>(k)] = k;
    rows = std::span<const int>(scratch.all);
  }
  std::vector<int>& batch = scratch.batch;
  map_rows(*rows, &batch);
  const int k = rows_->group_rows();
  std::vector<int>& groups = scratch.groups;
  groups.resize(batch.size());
  for (std::size_t q = 0; q < batch.size(); ++q) groups[q] = batch[q] / k;
  const bool ascending = std::is_sorted(groups.begin(), groups.end());
  if (!ascending) std::sort(groups.begin(), groups.end());
  groups.erase(std::unique(groups.begin(), groups.end()), groups.end());
  Evaluated out;
  std::vector<std::size_t>& start = scratch.start;
  if (rows_->single_block()) {
    out.evaluation = rows_->evaluate(groups, params, jacobians);
    start.resize(groups.size());
    for (std::size_t q = 0; q < groups.size(); ++q) start[q] = q * static_cast<std::size_t>(k);
  } else {
    out.evaluation = rows_->lookup(variables_, params, groups, jacobians, &start);
  }
  std::vector<std::size_t>& position = scratch.position;
  position.resize(batch.size());
  std::size_t q = 0;
  for (std::size_t i = 0; i < batch.size(); ++i) {
    const int g = batch[i] / k;
    if (ascending) {
      while (groups[q] != g) ++q;
    } else {
      q = static_cast<std::size_t>(std::lower_bound(groups.begin(), groups.end(), g) -
                                   groups.begin());
    }
    position[i] = start[q] + static_cast<std::size_t>(batch[i] % k);
  }
  out.position = position.data();
  return out;
}

void NumpyRowsBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                   double* residuals, double* jacobian) const {
  if (within_group(rows)) {  // an observation's rows: read straight from the batch's evaluation
    const auto k = static_cast<std::size_t>(rows_->group_rows());
    const bool weighted_rows = weighted();
    rows_->read_group(
        held_slots(), variables_, params, group_, jacobian != nullptr,
        [&](const RowsEvaluation& values, std::size_t w) {
          const double weight = weighted_rows ? values.group_weight(w) : 1.0;
          const StridedRows& r = values.residual_view();
          for (std::size_t q = 0; q < rows.size(); ++q) {
            residuals[q] =
                weight * r.in_row(r.group_row(w, static_cast<std::size_t>(rows[q]), k), 0);
          }
          if (jacobian == nullptr) return;
          const std::span<const int> dims = rows_->tangent_dims();
          double* out = jacobian;
          for (std::size_t q = 0; q < rows.size(); ++q) {
            for (std::size_t j = 0; j < dims.size(); ++j) {
              const StridedRows& view = values.jacobian_view(static_cast<int>(j));
              const char* start = view.group_row(w, static_cast<std::size_t>(rows[q]), k);
              for (int c = 0; c < dims[j]; ++c) *out++ = weight * view.in_row(start, c);
            }
          }
        });
    return;
  }
  const Evaluated e = evaluate(params, rows, jacobian != nullptr);
  const RowsEvaluation& values = *e.evaluation;
  const std::span<const int> dims = rows_->tangent_dims();
  const bool weighted_rows = weighted();
  const auto D = static_cast<std::size_t>(tangent_dim());
  bool direct = e.position == nullptr && !weighted_rows && whole_doubles(values.residual_view());
  for (std::size_t j = 0; direct && jacobian != nullptr && j < dims.size(); ++j) {
    direct = whole_doubles(values.jacobian_view(static_cast<int>(j)));
  }
  if (direct) {  // the first rows of the arrays, in order: copied as blocks
    const std::size_t m = rows.size();
    std::visit(
        [&](const auto& rv) {
          Eigen::Map<Eigen::VectorXd>(residuals, static_cast<Eigen::Index>(m)) =
              rv.head(static_cast<Eigen::Index>(m));
        },
        vector_of(values.residual_view(), m));
    if (jacobian == nullptr) return;
    Eigen::Index column = 0;
    for (std::size_t j = 0; j < dims.size(); ++j) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>, 0,
                 Eigen::OuterStride<>>
          out(jacobian + column, static_cast<Eigen::Index>(m), dims[j],
              Eigen::OuterStride<>(static_cast<Eigen::Index>(D)));
      std::visit([&](const auto& Jj) { out = Jj; },
                 matrix_of(values.jacobian_view(static_cast<int>(j)), m, dims[j]));
      column += dims[j];
    }
    return;
  }
  for (std::size_t q = 0; q < rows.size(); ++q) {
    const std::size_t i = e.at(q);
    const double w = weighted_rows ? values.weight(i) : 1.0;
    residuals[q] = w * values.residual(i);
    if (jacobian == nullptr) continue;
    double* out = jacobian + q * D;
    for (std::size_t j = 0; j < dims.size(); ++j) {
      const StridedRows& view = values.jacobian_view(static_cast<int>(j));
      const char* start = view.row(i);
      for (int c = 0; c < dims[j]; ++c) *out++ = w * view.in_row(start, c);
    }
  }
}

double NumpyRowsBlock::accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                                  Eigen::Ref<Eigen::VectorXd> b_r) const {
  const Evaluated e = evaluate(params, std::nullopt, true);
  const RowsEvaluation& values = *e.evaluation;
  const std::span<const int> dims = rows_->tangent_dims();
  const auto n = static_cast<std::size_t>(num_rows());
  const bool weighted_rows = weighted();
  const int D = tangent_dim();
  bool direct = e.position == nullptr && !weighted_rows && whole_doubles(values.residual_view());
  for (std::size_t j = 0; j < dims.size(); ++j) {
    direct = direct && whole_doubles(values.jacobian_view(static_cast<int>(j)));
  }
  if (direct) {  // the arrays as they are: products of maps, no copy of the rows
    const AnyVector r = vector_of(values.residual_view(), n);
    std::vector<AnyMatrix> J;
    for (std::size_t a = 0; a < dims.size(); ++a) {
      J.push_back(matrix_of(values.jacobian_view(static_cast<int>(a)), n, dims[a]));
    }
    // Chunks of rows that stay in cache while every product reads them: one pass over memory.
    double cost = 0.0;
    for (std::size_t begin = 0; begin < n; begin += kCacheRows) {
      const auto start = static_cast<Eigen::Index>(begin);
      const auto count = static_cast<Eigen::Index>(std::min(kCacheRows, n - begin));
      int column_a = 0;
      for (std::size_t a = 0; a < dims.size(); ++a) {
        std::visit(
            [&](const auto& Ja, const auto& rv) {
              b_r.segment(column_a, dims[a]).noalias() +=
                  Ja.middleRows(start, count).transpose().lazyProduct(rv.segment(start, count));
            },
            J[a], r);
        int column_b = column_a;
        for (std::size_t b = a; b < dims.size(); ++b) {
          std::visit(
              [&](const auto& Ja, const auto& Jb) {
                const auto A = Ja.middleRows(start, count).transpose();
                const auto B = Jb.middleRows(start, count);
                // A few columns: a handful of long dot products, without a blocked product's
                // packing; more: the blocked product.
                const Eigen::MatrixXd block = dims[a] <= kDotColumns && dims[b] <= kDotColumns
                                                  ? Eigen::MatrixXd(A.lazyProduct(B))
                                                  : Eigen::MatrixXd(A * B);
                H_r.block(column_a, column_b, dims[a], dims[b]) += block;
                if (a != b) H_r.block(column_b, column_a, dims[b], dims[a]) += block.transpose();
              },
              J[a], J[b]);
          column_b += dims[b];
        }
        column_a += dims[a];
      }
      cost += std::visit([&](const auto& rv) { return rv.segment(start, count).squaredNorm(); }, r);
    }
    return cost;
  }
  struct Scratch {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J;
    Eigen::VectorXd residual, b;
    Eigen::MatrixXd H;
  };
  thread_local Scratch scratch;
  const auto chunk = static_cast<Eigen::Index>(std::min<std::size_t>(kChunkRows, n));
  auto& J = scratch.J;
  auto& residual = scratch.residual;
  auto& H = scratch.H;
  auto& b = scratch.b;
  J.resize(chunk, D);
  residual.resize(chunk);
  H.setZero(D, D);
  b.setZero(D);
  double cost = 0.0;
  for (std::size_t begin = 0; begin < n; begin += static_cast<std::size_t>(chunk)) {
    const auto used = static_cast<Eigen::Index>(
        std::min<std::size_t>(static_cast<std::size_t>(chunk), n - begin));
    for (Eigen::Index q = 0; q < used; ++q) {
      const std::size_t i = e.at(begin + static_cast<std::size_t>(q));
      const double w = weighted_rows ? values.weight(i) : 1.0;
      residual[q] = w * values.residual(i);
      cost += weighted_rows ? values.cost_share(i) : residual[q] * residual[q];
      double* out = J.row(q).data();
      for (std::size_t j = 0; j < dims.size(); ++j) {
        const StridedRows& view = values.jacobian_view(static_cast<int>(j));
        const char* start = view.row(i);
        for (int c = 0; c < dims[j]; ++c) *out++ = w * view.in_row(start, c);
      }
    }
    if (used * 4 >= D) {
      H.selfadjointView<Eigen::Lower>().rankUpdate(J.topRows(used).transpose());
      b.noalias() += J.topRows(used).transpose() * residual.head(used);
      continue;
    }
    // A few rows (an observation's two): their products one by one beat a general rank update.
    for (Eigen::Index q = 0; q < used; ++q) {
      const double* row = J.row(q).data();
      for (int a = 0; a < D; ++a) {
        b[a] += row[a] * residual[q];
        double* column = H.col(a).data();
        for (int c = a; c < D; ++c) column[c] += row[c] * row[a];
      }
    }
  }
  H.triangularView<Eigen::StrictlyUpper>() = H.transpose();
  H_r += H;
  b_r += b;
  return cost;
}

double NumpyRowsBlock::squared_norm(ParameterPointers params) const {
  if (one_group_) {
    const auto k = static_cast<std::size_t>(rows_->group_rows());
    const bool weighted_rows = weighted();
    double cost = 0.0;
    rows_->read_group(held_slots(), variables_, params, group_, false,
                      [&](const RowsEvaluation& values, std::size_t w) {
                        const StridedRows& r = values.residual_view();
                        for (std::size_t c = 0; c < k; ++c) {
                          if (weighted_rows) {
                            cost += values.cost_share(w * k + c);
                          } else {
                            const double value = r.in_row(r.group_row(w, c, k), 0);
                            cost += value * value;
                          }
                        }
                      });
    return cost;
  }
  const Evaluated e = evaluate(params, std::nullopt, false);
  const RowsEvaluation& values = *e.evaluation;
  const auto n = static_cast<std::size_t>(num_rows());
  if (e.position == nullptr && !weighted() && whole_doubles(values.residual_view())) {
    return std::visit([](const auto& rv) { return rv.squaredNorm(); },
                      vector_of(values.residual_view(), n));
  }
  double cost = 0.0;
  if (weighted()) {
    for (std::size_t q = 0; q < n; ++q) cost += values.cost_share(e.at(q));
  } else {
    for (std::size_t q = 0; q < n; ++q) {
      const double r = values.residual(e.at(q));
      cost += r * r;
    }
  }
  return cost;
}

std::unique_ptr<ResidualBlock> NumpyRowsBlock::extract_rows(std::span<const int> rows) const {
  std::vector<int> batch;
  map_rows(rows, &batch);
  return std::make_unique<NumpyRowsBlock>(rows_, variables_, std::vector<int>{}, std::move(batch),
                                          with_loss_);
}

std::unique_ptr<ResidualBlock> NumpyRowsBlock::extract_rows_without_loss(
    ParameterPointers params, std::span<const int> rows, double* loss_weights) const {
  if (!weighted()) return nullptr;
  const Evaluated e = evaluate(params, rows, false);
  for (std::size_t q = 0; q < rows.size(); ++q) {
    const double w = e.evaluation->weight(e.at(q));
    loss_weights[q] = w * w;
  }
  std::vector<int> batch;
  map_rows(rows, &batch);
  return std::make_unique<NumpyRowsBlock>(rows_, variables_, std::vector<int>{}, std::move(batch),
                                          false);
}

}  // namespace carat::python
