#include "carat/residuals/pose_prior_block.hpp"

#include <Eigen/Cholesky>
#include <string>

#include "carat/base/error.hpp"
#include "carat/solver/so3.hpp"

namespace carat {

namespace {

template <typename Matrix>
Matrix upper_square_root(const Matrix& information, const char* what) {
  if (!information.allFinite()) {
    throw Error(std::string(what) + ": information matrix has non-finite entries");
  }
  const double scale = std::max(1.0, information.cwiseAbs().maxCoeff());
  if ((information - information.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    throw Error(std::string(what) + ": information matrix is not symmetric");
  }
  const Eigen::LLT<Matrix> llt(information);
  if (llt.info() != Eigen::Success ||
      !(llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 0.0)) {
    throw Error(std::string(what) + ": information matrix is not positive definite");
  }
  return llt.matrixU();
}

}  // namespace

se3::Matrix6d sqrt_information(const se3::Matrix6d& information, const char* what) {
  return upper_square_root(information, what);
}

Eigen::Matrix3d sqrt_information(const Eigen::Matrix3d& information, const char* what) {
  return upper_square_root(information, what);
}

PosePriorBlock::PosePriorBlock(const Eigen::Isometry3d& T_world_prior,
                               const se3::Matrix6d& information)
    : q_prior_inverse_(Eigen::Quaterniond(T_world_prior.linear()).normalized().conjugate()),
      t_prior_(T_world_prior.translation()),
      R_prior_transpose_(q_prior_inverse_.toRotationMatrix()),
      sqrt_info_(sqrt_information(information, "PosePriorBlock")) {}

void PosePriorBlock::evaluate(const double* pose, Eigen::Matrix<double, 6, 1>* r,
                              Eigen::Matrix<double, 6, 6>* J) const {
  const Eigen::Map<const Eigen::Quaterniond> q(pose);
  const Eigen::Map<const Eigen::Vector3d> t(pose + 4);
  const Eigen::Quaterniond q_error = q_prior_inverse_ * q;
  Eigen::Matrix<double, 6, 1> e;
  e.head<3>() = R_prior_transpose_ * (t - t_prior_);
  e.tail<3>() = 2.0 * q_error.vec();
  *r = sqrt_info_ * e;
  if (J == nullptr) return;
  Eigen::Matrix<double, 6, 6> de = Eigen::Matrix<double, 6, 6>::Zero();
  de.block<3, 3>(0, 3) = R_prior_transpose_ * q.toRotationMatrix();
  de.block<3, 3>(3, 0) = q_error.w() * Eigen::Matrix3d::Identity() + so3::hat(q_error.vec());
  *J = sqrt_info_ * de;
}

void PosePriorBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                   double* residuals, double* jacobian) const {
  Eigen::Matrix<double, 6, 1> r;
  Eigen::Matrix<double, 6, 6> J;
  evaluate(params[0], &r, jacobian ? &J : nullptr);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    residuals[k] = r[rows[k]];
    if (jacobian) {
      for (int c = 0; c < 6; ++c) jacobian[k * 6 + static_cast<std::size_t>(c)] = J(rows[k], c);
    }
  }
}

}  // namespace carat
