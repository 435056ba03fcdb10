#include "carat/residuals/relative_pose_se2_block.hpp"

#include "carat/residuals/pose_prior_block.hpp"
#include "carat/solver/se2.hpp"

namespace carat {
namespace {

/// Rows of a tangent [w, vx, vy] in the residual's order [vx, vy, w].
Eigen::Matrix3d translation_first() {
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  P(0, 1) = P(1, 2) = P(2, 0) = 1.0;
  return P;
}

}  // namespace

RelativePoseSE2Block::RelativePoseSE2Block(const Eigen::Isometry2d& T_i_j,
                                           const Eigen::Matrix3d& information)
    : T_i_j_(se2::make(T_i_j.translation().x(), T_i_j.translation().y(), se2::angle(T_i_j))),
      T_j_i_(T_i_j_.inverse()),
      sqrt_info_(carat::sqrt_information(information, "RelativePoseSE2Block")) {}

void RelativePoseSE2Block::evaluate(const double* pose_i, const double* pose_j, Eigen::Vector3d* r,
                                    Eigen::Matrix<double, 3, 6>* J) const {
  const Eigen::Isometry2d T_world_i = se2::from_storage(pose_i);
  const Eigen::Isometry2d T_world_j = se2::from_storage(pose_j);
  const Eigen::Isometry2d T_i_j_estimate = T_world_i.inverse() * T_world_j;
  const Eigen::Vector3d xi = se2::log(T_j_i_ * T_i_j_estimate);
  const Eigen::Vector3d e(xi[1], xi[2], xi[0]);
  *r = sqrt_info_ * e;
  if (J == nullptr) return;
  // E = Z^-1 T_i^-1 T_j. T_j Exp(d) gives E Exp(d); T_i Exp(d) gives E Exp(-Ad(T_j^-1 T_i) d).
  const Eigen::Matrix3d J_r_inverse = se2::right_jacobian_inverse(xi);
  const Eigen::Matrix3d d_xi_j = J_r_inverse;
  const Eigen::Matrix3d d_xi_i = -J_r_inverse * se2::adjoint(T_i_j_estimate.inverse());
  const Eigen::Matrix3d U_P = sqrt_info_ * translation_first();
  J->leftCols<3>() = U_P * d_xi_i;
  J->rightCols<3>() = U_P * d_xi_j;
}

void RelativePoseSE2Block::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                         double* residuals, double* jacobian) const {
  Eigen::Vector3d r;
  Eigen::Matrix<double, 3, 6> J;
  evaluate(params[0], params[1], &r, jacobian ? &J : nullptr);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    residuals[k] = r[rows[k]];
    if (jacobian) {
      for (int c = 0; c < 6; ++c) jacobian[k * 6 + static_cast<std::size_t>(c)] = J(rows[k], c);
    }
  }
}

double RelativePoseSE2Block::accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                                        Eigen::Ref<Eigen::VectorXd> b_r) const {
  Eigen::Vector3d r;
  Eigen::Matrix<double, 3, 6> J;
  evaluate(params[0], params[1], &r, &J);
  const Eigen::Matrix<double, 6, 6> H = J.transpose().lazyProduct(J);
  const Eigen::Matrix<double, 6, 1> b = J.transpose().lazyProduct(r);
  H_r += H;
  b_r += b;
  return r.squaredNorm();
}

double RelativePoseSE2Block::squared_norm(ParameterPointers params) const {
  Eigen::Vector3d r;
  evaluate(params[0], params[1], &r, nullptr);
  return r.squaredNorm();
}

}  // namespace carat
