#include "carat/solver/residual_block.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "carat/solver/error.hpp"

namespace carat {
namespace {
constexpr int kChunkRows = 128;
}

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
  std::vector<int> rows(static_cast<std::size_t>(std::min(n, kChunkRows)));
  Eigen::VectorXd residuals(static_cast<Eigen::Index>(rows.size()));
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(
      static_cast<Eigen::Index>(rows.size()), r);
  double c = 0.0;
  for (int begin = 0; begin < n; begin += kChunkRows) {
    const int count = std::min(kChunkRows, n - begin);
    std::iota(rows.begin(), rows.begin() + count, begin);
    evaluate_rows(params, std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
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
  std::vector<int> rows(static_cast<std::size_t>(std::min(n, kChunkRows)));
  std::vector<double> residuals(rows.size());
  double c = 0.0;
  for (int begin = 0; begin < n; begin += kChunkRows) {
    const int count = std::min(kChunkRows, n - begin);
    std::iota(rows.begin(), rows.begin() + count, begin);
    evaluate_rows(params, std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
                  residuals.data(), nullptr);
    for (int k = 0; k < count; ++k)
      c += residuals[static_cast<std::size_t>(k)] * residuals[static_cast<std::size_t>(k)];
  }
  return c;
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
