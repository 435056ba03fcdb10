#include "carat/residuals/lossless_block.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/residuals/registration_rows.hpp"

namespace carat {
namespace {

/// A largest remaining diagonal (a squared pivot, G scaled to a unit diagonal) at or below this
/// ends the factor: the rank is numerical.
constexpr double kRankTolerance = 1e-13;
/// A remaining diagonal below minus this means G is not positive semidefinite.
constexpr double kNegativeTolerance = 1e-9;

using Matrix13 = Eigen::Matrix<double, 13, 13>;
using Vector13 = Eigen::Matrix<double, 13, 1>;

/// A number as %g (std::to_string prints six fixed decimals: -3e-9 would read -0.000000).
std::string number(double x) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", x);
  return text;
}

}  // namespace

LosslessRegistrationBlock::LosslessRegistrationBlock(const PoseGram& gram)
    : embedding_(gram.embedding), original_rows_(gram.rows) {
  const Matrix13& G = gram.gram;
  const char* who = "LosslessRegistrationBlock: ";
  if (!G.allFinite()) throw Error(std::string(who) + "the Gram matrix is not finite");
  if (!embedding_.R_target_source_reference.allFinite() ||
      !embedding_.t_target_source_reference.allFinite() || !embedding_.source_centre.allFinite())
    throw Error(std::string(who) + "the reference pose or the source centre is not finite");
  const double magnitude = G.cwiseAbs().maxCoeff();
  if (!(magnitude > 0.0)) throw Error(std::string(who) + "the Gram matrix is zero");
  if ((G - G.transpose()).cwiseAbs().maxCoeff() > 1e-12 * magnitude)
    throw Error(std::string(who) + "the Gram matrix is not symmetric");

  // Scale to a unit diagonal (coordinates with a zero diagonal must have zero rows and columns
  // in a positive semidefinite G, and are left out), then pivoted Cholesky on the scaled matrix
  // A: A[order, order] = U^T U with U upper triangular.
  std::array<double, 13> scale{};
  for (int i = 0; i < 13; ++i) {
    if (G(i, i) < 0.0)
      throw Error(std::string(who) + "the Gram matrix is not positive semidefinite (diagonal " +
                  std::to_string(i) + " is " + number(G(i, i)) + ")");
    if (G(i, i) == 0.0 && G.row(i).cwiseAbs().maxCoeff() > 0.0)
      throw Error(std::string(who) + "the Gram matrix is not positive semidefinite (diagonal " +
                  std::to_string(i) + " is 0 but row " + std::to_string(i) + " is not)");
    scale[static_cast<std::size_t>(i)] = std::sqrt(G(i, i));
  }
  Matrix13 A = Matrix13::Zero();
  for (int i = 0; i < 13; ++i) {
    for (int j = 0; j < 13; ++j) {
      const double si = scale[static_cast<std::size_t>(i)], sj = scale[static_cast<std::size_t>(j)];
      if (si > 0.0 && sj > 0.0) A(i, j) = G(i, j) / si / sj;
    }
  }
  std::array<int, 13> order{};
  for (int i = 0; i < 13; ++i) order[static_cast<std::size_t>(i)] = i;
  Matrix13 U = Matrix13::Zero();
  const double largest = A.diagonal().maxCoeff();  // 1: some diagonal is not zero (G is not)
  int rank = 0;
  for (int k = 0; k < 13; ++k) {
    int q = k;
    for (int i = k + 1; i < 13; ++i) {
      if (A(i, i) > A(q, q)) q = i;
    }
    if (!(A(q, q) > kRankTolerance * largest)) {
      const double lowest = A.diagonal().tail(13 - k).minCoeff();
      if (lowest < -kNegativeTolerance * largest)
        throw Error(std::string(who) + "the Gram matrix is not positive semidefinite (a pivot of " +
                    std::to_string(lowest) + " after scaling)");
      break;
    }
    if (q != k) {
      A.row(k).swap(A.row(q));
      A.col(k).swap(A.col(q));
      U.col(k).swap(U.col(q));
      std::swap(order[static_cast<std::size_t>(k)], order[static_cast<std::size_t>(q)]);
    }
    const double pivot = std::sqrt(A(k, k));
    U(k, k) = pivot;
    for (int j = k + 1; j < 13; ++j) U(k, j) = A(k, j) / pivot;
    for (int i = k + 1; i < 13; ++i) {
      for (int j = i; j < 13; ++j) {
        A(i, j) -= U(k, i) * U(k, j);
        A(j, i) = A(i, j);
      }
    }
    rank = k + 1;
  }
  if (rank == 0) throw Error(std::string(who) + "the Gram matrix has no positive pivot");
  rank_ = rank;
  // V = U diag(scale[order]): r = V (y[order]) reproduces y^T G y.
  for (int i = 0; i < rank_; ++i) {
    for (int j = i; j < 13; ++j) {
      upper_[static_cast<std::size_t>(row_offset(i) + j - i)] =
          U(i, j) * scale[static_cast<std::size_t>(order[static_cast<std::size_t>(j)])];
    }
  }
  for (int j = 0; j < 13; ++j)
    order_[static_cast<std::size_t>(j)] =
        static_cast<std::uint8_t>(order[static_cast<std::size_t>(j)]);
}

void LosslessRegistrationBlock::reduced_map(ParameterPointers params, double* A) const {
  relative_pose_reduced_map(params, A);
}

void LosslessRegistrationBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                              double* residuals, double* jacobian) const {
  const Eigen::Isometry3d T = relative_pose(params);
  const Vector13 y = embedding_.value(T);
  Vector13 yp;
  Eigen::Matrix<double, 13, 6> Dp;
  if (jacobian) {
    const Eigen::Matrix<double, 13, 6> D = embedding_.jacobian(T);
    for (int j = 0; j < 13; ++j) Dp.row(j) = D.row(order_[static_cast<std::size_t>(j)]);
  }
  for (int j = 0; j < 13; ++j) yp[j] = y[order_[static_cast<std::size_t>(j)]];
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const int i = rows[k];
    const double* v = upper_.data() + row_offset(i);
    const int n = 13 - i;
    residuals[k] = Eigen::Map<const Eigen::VectorXd>(v, n).dot(yp.tail(n));
    if (jacobian) {
      Eigen::Map<Eigen::Matrix<double, 1, 6>> J(jacobian + 6 * k);
      J = Eigen::Map<const Eigen::RowVectorXd>(v, n) * Dp.bottomRows(n);
    }
  }
}

std::size_t LosslessRegistrationBlock::memory_bytes() const {
  return sizeof(upper_) + sizeof(PoseEmbedding) + sizeof(order_);
}

std::shared_ptr<const LosslessRegistrationBlock> make_lossless_block(
    const AffinePoseRows& block, const Eigen::Isometry3d& T_target_source_reference) {
  return std::make_shared<const LosslessRegistrationBlock>(
      block.pose_gram(T_target_source_reference));
}

std::shared_ptr<const ResidualBlock> lossless_form(const AffinePoseRows& block,
                                                   ParameterPointers params) {
  return make_lossless_block(block, relative_pose(params));
}

}  // namespace carat
