#include "carat/residuals/registration_rows.hpp"

#include "carat/solver/se3.hpp"

namespace carat {

Eigen::Isometry3d relative_pose(ParameterPointers params) {
  return se3::from_storage(params[0]).inverse() * se3::from_storage(params[1]);
}

void relative_pose_reduced_map(ParameterPointers params, double* A) {
  Eigen::Map<Eigen::Matrix<double, 6, 12, Eigen::RowMajor>> map(A);
  // T_i <- T_i Exp(xi_i) moves T_ij to Exp(-xi_i) T_ij = T_ij Exp(-Ad(T_ij^-1) xi_i);
  // T_j <- T_j Exp(xi_j) moves T_ij to T_ij Exp(xi_j).
  map.leftCols<6>() = -se3::adjoint(relative_pose(params).inverse());
  map.rightCols<6>().setIdentity();
}

}  // namespace carat
