#include "carat/residuals/relative_pose_block.hpp"

#include "carat/residuals/pose_prior_block.hpp"
#include "carat/solver/so3.hpp"

namespace carat {

RelativePoseBlock::RelativePoseBlock(const Eigen::Isometry3d& T_i_j,
                                     const se3::Matrix6d& information)
    : q_ij_(Eigen::Quaterniond(T_i_j.linear()).normalized()),
      t_ij_(T_i_j.translation()),
      R_ij_transpose_(q_ij_.toRotationMatrix().transpose()),
      sqrt_info_(carat::sqrt_information(information, "RelativePoseBlock")) {}

void RelativePoseBlock::evaluate(const double* pose_i, const double* pose_j,
                                 Eigen::Matrix<double, 6, 1>* r,
                                 Eigen::Matrix<double, 6, 12>* J) const {
  const Eigen::Map<const Eigen::Quaterniond> q_i(pose_i);
  const Eigen::Map<const Eigen::Vector3d> t_i(pose_i + 4);
  const Eigen::Map<const Eigen::Quaterniond> q_j(pose_j);
  const Eigen::Map<const Eigen::Vector3d> t_j(pose_j + 4);
  const Eigen::Quaterniond q_i_inverse = q_i.conjugate();
  const Eigen::Matrix3d R_i_transpose = q_i_inverse.toRotationMatrix();
  const Eigen::Vector3d t_ij_estimate = R_i_transpose * (t_j - t_i);
  const Eigen::Quaterniond q_error = q_ij_.conjugate() * (q_i_inverse * q_j);
  Eigen::Matrix<double, 6, 1> e;
  e.head<3>() = t_ij_estimate - t_ij_;
  e.tail<3>() = 2.0 * q_error.vec();
  *r = sqrt_info_ * e;
  if (J == nullptr) return;
  const double w = q_error.w();
  const Eigen::Matrix3d V = so3::hat(q_error.vec());
  Eigen::Matrix<double, 6, 12> de = Eigen::Matrix<double, 6, 12>::Zero();
  de.block<3, 3>(0, 0) = so3::hat(t_ij_estimate);                 // d e_t / d omega_i
  de.block<3, 3>(0, 3) = -Eigen::Matrix3d::Identity();            // d e_t / d v_i
  de.block<3, 3>(0, 9) = R_i_transpose * q_j.toRotationMatrix();  // d e_t / d v_j
  de.block<3, 3>(3, 0) =
      -(w * Eigen::Matrix3d::Identity() - V) * R_ij_transpose_;  // d e_r / d omega_i
  de.block<3, 3>(3, 6) = w * Eigen::Matrix3d::Identity() + V;    // d e_r / d omega_j
  *J = sqrt_info_ * de;
}

void RelativePoseBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                      double* residuals, double* jacobian) const {
  Eigen::Matrix<double, 6, 1> r;
  Eigen::Matrix<double, 6, 12> J;
  evaluate(params[0], params[1], &r, jacobian ? &J : nullptr);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    residuals[k] = r[rows[k]];
    if (jacobian) {
      for (int c = 0; c < 12; ++c) jacobian[k * 12 + static_cast<std::size_t>(c)] = J(rows[k], c);
    }
  }
}

double RelativePoseBlock::accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                                     Eigen::Ref<Eigen::VectorXd> b_r) const {
  Eigen::Matrix<double, 6, 1> r;
  Eigen::Matrix<double, 6, 12> J;
  evaluate(params[0], params[1], &r, &J);
  // Fixed-size, coefficient-wise products: Eigen would send a 12 x 6 by 6 x 12 product
  // through its general GEMM kernel (packing included), several times slower at this size.
  const Eigen::Matrix<double, 12, 12> H = J.transpose().lazyProduct(J);
  const Eigen::Matrix<double, 12, 1> b = J.transpose().lazyProduct(r);
  H_r += H;
  b_r += b;
  return r.squaredNorm();
}

double RelativePoseBlock::squared_norm(ParameterPointers params) const {
  Eigen::Matrix<double, 6, 1> r;
  evaluate(params[0], params[1], &r, nullptr);
  return r.squaredNorm();
}

}  // namespace carat
