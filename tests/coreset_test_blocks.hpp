#pragma once

// A binary registration-style block for the coreset tests: point-to-plane rows
// r_k = n_k . (T_ij p_k - q_k) with T_ij = T_i^-1 T_j, reduced to the 6-D tangent of T_ij.

#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <vector>

#include "carat/solver/residual_block.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/so3.hpp"

namespace carat::test {

class PlaneBlock final : public ResidualBlock {
 public:
  PlaneBlock(std::vector<Eigen::Vector3d> p, std::vector<Eigen::Vector3d> q,
             std::vector<Eigen::Vector3d> n)
      : p_(std::move(p)), q_(std::move(q)), n_(std::move(n)) {}

  int num_rows() const override { return static_cast<int>(p_.size()); }
  std::span<const int> tangent_dims() const override { return dims_; }
  int reduced_dim() const override { return 6; }

  static Eigen::Isometry3d relative(ParameterPointers params) {
    return se3::from_storage(params[0]).inverse() * se3::from_storage(params[1]);
  }

  // J_i = J_r (-Ad(T_ij^-1)), J_j = J_r.
  void reduced_map(ParameterPointers params, double* A) const override {
    Eigen::Map<Eigen::Matrix<double, 6, 12, Eigen::RowMajor>> map(A);
    map.leftCols<6>() = -se3::adjoint(relative(params).inverse());
    map.rightCols<6>().setIdentity();
  }

  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    const Eigen::Isometry3d T = relative(params);
    const Eigen::Matrix3d R = T.linear();
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto i = static_cast<std::size_t>(rows[k]);
      residuals[k] = n_[i].dot(T * p_[i] - q_[i]);
      if (!jacobian) continue;
      // d/dxi of T Exp(xi) p = R (-[p]x omega + v).
      const Eigen::Vector3d nR = R.transpose() * n_[i];
      const Eigen::Vector3d d_omega = p_[i].cross(nR);
      for (int c = 0; c < 3; ++c) {
        jacobian[k * 6 + static_cast<std::size_t>(c)] = d_omega[c];
        jacobian[k * 6 + 3 + static_cast<std::size_t>(c)] = nR[c];
      }
    }
  }

  std::unique_ptr<ResidualBlock> extract_rows(std::span<const int> rows) const override {
    std::vector<Eigen::Vector3d> p, q, n;
    for (int r : rows) {
      p.push_back(p_[static_cast<std::size_t>(r)]);
      q.push_back(q_[static_cast<std::size_t>(r)]);
      n.push_back(n_[static_cast<std::size_t>(r)]);
    }
    return std::make_unique<PlaneBlock>(std::move(p), std::move(q), std::move(n));
  }

  std::size_t memory_bytes() const override { return p_.size() * 3 * sizeof(Eigen::Vector3d); }

 private:
  std::vector<Eigen::Vector3d> p_, q_, n_;
  std::array<int, 2> dims_{6, 6};
};

}  // namespace carat::test
