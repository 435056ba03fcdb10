#include "carat/solver/se3.hpp"

#include "carat/solver/so3.hpp"
#include "rigid_check.hpp"

namespace carat::se3 {

Eigen::Isometry3d exp(const Vector6d& xi) {
  const Eigen::Vector3d omega = xi.head<3>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = so3::exp(omega).toRotationMatrix();
  T.translation() = so3::left_jacobian(omega) * xi.tail<3>();
  return T;
}

Vector6d log(const Eigen::Isometry3d& T) {
  Vector6d xi;
  const Eigen::Vector3d omega = so3::log(Eigen::Quaterniond(T.linear()));
  xi.head<3>() = omega;
  // J_l^-1(w) = J_r^-1(-w).
  xi.tail<3>() = so3::right_jacobian_inverse(-omega) * T.translation();
  return xi;
}

Matrix6d adjoint(const Eigen::Isometry3d& T) {
  Matrix6d Ad = Matrix6d::Zero();
  const Eigen::Matrix3d R = T.linear();
  Ad.topLeftCorner<3, 3>() = R;
  Ad.bottomRightCorner<3, 3>() = R;
  Ad.bottomLeftCorner<3, 3>() = so3::hat(T.translation()) * R;
  return Ad;
}

Eigen::Isometry3d from_storage(const double* storage) {
  const Eigen::Quaterniond q(storage[3], storage[0], storage[1], storage[2]);
  return make(q, Eigen::Vector3d(storage[4], storage[5], storage[6]));
}

void to_storage(const Eigen::Isometry3d& T, double* storage) {
  Eigen::Quaterniond q(T.linear());
  q.normalize();
  storage[0] = q.x();
  storage[1] = q.y();
  storage[2] = q.z();
  storage[3] = q.w();
  storage[4] = T.translation().x();
  storage[5] = T.translation().y();
  storage[6] = T.translation().z();
}

Eigen::Isometry3d make(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

const char* rigid_transform_problem(const Eigen::Isometry3d& T) {
  return internal::rigid_problem(T);
}

}  // namespace carat::se3
