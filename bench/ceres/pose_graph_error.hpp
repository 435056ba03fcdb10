#pragma once
// The pose-graph residual of Ceres's pose_graph_3d example setup, for the comparison benchmarks:
// [R_a^T (p_b - p_a) - p_ab; 2 vec(q_ab^-1 q_a^-1 q_b)], whitened by the square-root information
// (translation first). carat's RelativePoseBlock computes the same function.
#include <Eigen/Core>
#include <Eigen/Geometry>

/// Ceres's relative-pose residual over two [p, q] parameter blocks (3 + 4 numbers each).
struct PoseGraphError {
  PoseGraphError(const Eigen::Vector3d& p_ab, const Eigen::Quaterniond& q_ab,
                 const Eigen::Matrix<double, 6, 6>& sqrt_information)
      : p_ab_(p_ab), q_ab_(q_ab), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* pose_a, const T* pose_b, T* residuals) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(pose_a);
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(pose_a + 3);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_b(pose_b);
    const Eigen::Map<const Eigen::Quaternion<T>> q_b(pose_b + 3);
    const Eigen::Quaternion<T> q_a_inverse = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab_estimated = q_a_inverse * q_b;
    const Eigen::Matrix<T, 3, 1> p_ab_estimated = q_a_inverse * (p_b - p_a);
    const Eigen::Quaternion<T> delta_q = q_ab_.template cast<T>().conjugate() * q_ab_estimated;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residuals);
    r.template head<3>() = p_ab_estimated - p_ab_.template cast<T>();
    r.template tail<3>() = T(2.0) * delta_q.vec();
    r.applyOnTheLeft(sqrt_information_.template cast<T>());
    return true;
  }

  Eigen::Vector3d p_ab_;
  Eigen::Quaterniond q_ab_;
  Eigen::Matrix<double, 6, 6> sqrt_information_;
};
