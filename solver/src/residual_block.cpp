#include "carat/solver/residual_block.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {
namespace {

constexpr int kChunkRows = 128;

/// A NaN with a payload no block computes by chance: what evaluate_rows_checked() puts in the
/// slots a block must write (each must change) and in the row after them (which must not).
constexpr std::uint64_t kGuardBits = 0x7ff8dead0000f00dULL;

double guard_value() {
  double value;
  std::memcpy(&value, &kGuardBits, sizeof(value));
  return value;
}

bool is_guard(double x) {
  std::uint64_t bits;
  std::memcpy(&bits, &x, sizeof(bits));
  return bits == kGuardBits;
}

std::string block_label(const ResidualBlock& block) {
  return block.name().empty() ? std::string("residual block")
                              : "residual block '" + block.name() + "'";
}

}  // namespace

int ResidualBlock::tangent_dim() const {
  const auto dims = tangent_dims();
  return std::accumulate(dims.begin(), dims.end(), 0);
}

void ResidualBlock::reduced_map(ParameterPointers /*params*/, double* A) const {
  const int r = reduced_dim();
  const int d = tangent_dim();
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> map(A, r, d);
  map.setIdentity();
}

double ResidualBlock::accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                                 Eigen::Ref<Eigen::VectorXd> b_r) const {
  const int n = num_rows();
  const int r = reduced_dim();
  const int chunk = std::min(n, kChunkRows);
  std::vector<int> rows(static_cast<std::size_t>(chunk));
  Eigen::VectorXd residuals(chunk);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(chunk, r);
  double c = constant_cost();
  for (int begin = 0; begin < n; begin += kChunkRows) {
    const int count = std::min(kChunkRows, n - begin);
    std::iota(rows.begin(), rows.begin() + count, begin);
    evaluate_rows_checked(*this, params,
                          std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
                          residuals.data(), J.data());
    const auto Jc = J.topRows(count);
    const auto ec = residuals.head(count);
    H_r.selfadjointView<Eigen::Lower>().rankUpdate(Jc.transpose());
    b_r.noalias() += Jc.transpose() * ec;
    c += ec.squaredNorm();
  }
  H_r.triangularView<Eigen::StrictlyUpper>() = H_r.transpose();
  return c;
}

double ResidualBlock::squared_norm(ParameterPointers params) const {
  const int n = num_rows();
  const int chunk = std::min(n, kChunkRows);
  std::vector<int> rows(static_cast<std::size_t>(chunk));
  std::vector<double> residuals(static_cast<std::size_t>(chunk));
  double c = constant_cost();
  for (int begin = 0; begin < n; begin += kChunkRows) {
    const int count = std::min(kChunkRows, n - begin);
    std::iota(rows.begin(), rows.begin() + count, begin);
    evaluate_rows_checked(*this, params,
                          std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
                          residuals.data(), nullptr);
    for (int k = 0; k < count; ++k)
      c += residuals[static_cast<std::size_t>(k)] * residuals[static_cast<std::size_t>(k)];
  }
  return c;
}

void evaluate_rows_checked(const ResidualBlock& block, ParameterPointers params,
                           std::span<const int> rows, double* residuals, double* jacobian) {
  const auto count = rows.size();
  const auto r = static_cast<std::size_t>(block.reduced_dim());
  // Room for every row the block has (a careless block writes them all), allocated without
  // being touched, so that only the pages a block writes cost memory.
  const std::size_t capacity = std::max(count + 1, static_cast<std::size_t>(block.num_rows()));
  const std::unique_ptr<double[]> storage(new double[capacity * (jacobian ? r + 1 : 1)]);
  double* const scratch = storage.get();
  double* const e = scratch;
  double* const J = jacobian ? scratch + capacity : nullptr;
  std::fill_n(e, count + 1, guard_value());
  if (J) std::fill_n(J, (count + 1) * r, guard_value());
  block.evaluate_rows(params, rows, e, J);
  const auto wrote_past = [&] {
    throw Error(block_label(block) + ": evaluate_rows() asked for " + std::to_string(count) +
                " rows wrote past them; it must write exactly the rows in `rows`, residual k for "
                "rows[k] (check_residual_block() shows how it fails)");
  };
  const auto left_unwritten = [&](std::size_t k) {
    throw Error(block_label(block) + ": evaluate_rows() asked for " + std::to_string(count) +
                " rows left " + (jacobian ? "the residual or Jacobian" : "the residual") +
                " of row " + std::to_string(rows[k]) + " (slot " + std::to_string(k) +
                ") unwritten; it must write every row in `rows`");
  };
  if (!is_guard(e[count])) wrote_past();
  if (J) {
    for (std::size_t c = 0; c < r; ++c) {
      if (!is_guard(J[count * r + c])) wrote_past();
    }
  }
  for (std::size_t k = 0; k < count; ++k) {
    if (is_guard(e[k])) left_unwritten(k);
    if (J) {
      for (std::size_t c = 0; c < r; ++c) {
        if (is_guard(J[k * r + c])) left_unwritten(k);
      }
    }
  }
  std::copy_n(e, count, residuals);
  if (J) std::copy_n(J, count * r, jacobian);
}

const std::string& ResidualBlock::name() const {
  static const std::string kNone;
  return kNone;
}

std::unique_ptr<ResidualBlock> ResidualBlock::extract_rows_without_loss(
    ParameterPointers /*params*/, std::span<const int> /*rows*/, double* /*loss_weights*/) const {
  return nullptr;
}

std::shared_ptr<const ResidualBlock> ResidualBlock::exact_form(ParameterPointers /*params*/) const {
  return nullptr;
}

std::unique_ptr<ResidualBlock> ResidualBlock::extract_rows(std::span<const int> /*rows*/) const {
  return nullptr;
}

void ResidualBlock::check_row_weights(const char* who, std::span<const int> rows,
                                      std::span<const double> weights) {
  if (rows.size() != weights.size()) {
    throw Error(std::string(who) + ": " + std::to_string(rows.size()) + " rows but " +
                std::to_string(weights.size()) + " weights");
  }
  for (std::size_t k = 0; k < weights.size(); ++k) {
    if (!std::isfinite(weights[k]) || !(weights[k] > 0.0)) {
      throw Error(std::string(who) + ": weight " + std::to_string(k) + " is " +
                  std::to_string(weights[k]) + "; weights must be finite and > 0");
    }
  }
}

std::unique_ptr<ResidualBlock> ResidualBlock::extract_weighted_rows(
    std::span<const int> /*rows*/, std::span<const double> /*weights*/) const {
  return nullptr;
}

}  // namespace carat
