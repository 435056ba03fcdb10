#include "carat/solver/residual_block.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <string>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {
namespace {

constexpr int kChunkRows = 128;

/// Rows after a chunk that are watched for writes: a block's evaluate_rows() must write only
/// the rows it was asked for. Debug builds watch every row a careless block could write (all N),
/// so that the write lands in this buffer and is reported; release builds watch one row.
int guard_rows(int n, int count) {
#ifdef NDEBUG
  (void)n;
  (void)count;
  return 1;
#else
  return std::max(1, n - count);
#endif
}

constexpr std::uint64_t kGuardBits = 0x7ff8dead0000f00dULL;

double guard_value() {
  double value;
  std::memcpy(&value, &kGuardBits, sizeof(value));
  return value;
}

bool untouched(const double* x, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t bits;
    std::memcpy(&bits, x + i, sizeof(bits));
    if (bits != kGuardBits) return false;
  }
  return true;
}

[[noreturn]] void wrote_past(int count) {
  throw Error("residual block: evaluate_rows() asked for " + std::to_string(count) +
              " rows wrote past them; it must write only the rows in `rows` (check it with "
              "check_residual_block())");
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
  const int guard = guard_rows(n, chunk);
  std::vector<int> rows(static_cast<std::size_t>(chunk));
  Eigen::VectorXd residuals(chunk + guard);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(chunk + guard, r);
  double c = 0.0;
  for (int begin = 0; begin < n; begin += kChunkRows) {
    const int count = std::min(kChunkRows, n - begin);
    std::iota(rows.begin(), rows.begin() + count, begin);
    residuals.tail(chunk + guard - count).setConstant(guard_value());
    J.bottomRows(chunk + guard - count).setConstant(guard_value());
    evaluate_rows(params, std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
                  residuals.data(), J.data());
    if (!untouched(residuals.data() + count, static_cast<std::size_t>(chunk + guard - count)) ||
        !untouched(J.data() + static_cast<std::size_t>(count) * r,
                   static_cast<std::size_t>(chunk + guard - count) * r)) {
      wrote_past(count);
    }
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
  const int guard = guard_rows(n, chunk);
  std::vector<int> rows(static_cast<std::size_t>(chunk));
  std::vector<double> residuals(static_cast<std::size_t>(chunk + guard));
  double c = 0.0;
  for (int begin = 0; begin < n; begin += kChunkRows) {
    const int count = std::min(kChunkRows, n - begin);
    std::iota(rows.begin(), rows.begin() + count, begin);
    std::fill(residuals.begin() + count, residuals.end(), guard_value());
    evaluate_rows(params, std::span<const int>(rows.data(), static_cast<std::size_t>(count)),
                  residuals.data(), nullptr);
    if (!untouched(residuals.data() + count, residuals.size() - static_cast<std::size_t>(count))) {
      wrote_past(count);
    }
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
