#pragma once

// Small residual blocks used by the solver tests.

#include <Eigen/Core>
#include <array>
#include <vector>

#include "carat/solver/residual_block.hpp"

namespace carat::test {

/// r = sum_v A_v x_v - y over Euclidean variables (a linear least-squares block).
class LinearBlock final : public ResidualBlock {
 public:
  /// One matrix per variable (rows x dim_v), and the target y.
  LinearBlock(std::vector<Eigen::MatrixXd> A, Eigen::VectorXd y)
      : A_(std::move(A)), y_(std::move(y)) {
    for (const auto& a : A_) dims_.push_back(static_cast<int>(a.cols()));
  }
  int num_rows() const override { return static_cast<int>(y_.size()); }
  std::span<const int> tangent_dims() const override { return dims_; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    Eigen::VectorXd r = -y_;
    for (std::size_t v = 0; v < A_.size(); ++v) {
      r += A_[v] * Eigen::Map<const Eigen::VectorXd>(params[v], A_[v].cols());
    }
    const int D = tangent_dim();
    for (std::size_t k = 0; k < rows.size(); ++k) {
      residuals[k] = r[rows[k]];
      if (!jacobian) continue;
      int col = 0;
      for (const auto& a : A_) {
        for (int c = 0; c < a.cols(); ++c)
          jacobian[k * static_cast<std::size_t>(D) + static_cast<std::size_t>(col++)] =
              a(rows[k], c);
      }
    }
  }
  std::size_t memory_bytes() const override { return sizeof(*this); }

 private:
  std::vector<Eigen::MatrixXd> A_;
  Eigen::VectorXd y_;
  std::vector<int> dims_;
};

/// Rosenbrock as two residuals over one 2-vector: r = [10 (x1 - x0^2), 1 - x0].
class RosenbrockBlock final : public ResidualBlock {
 public:
  int num_rows() const override { return 2; }
  std::span<const int> tangent_dims() const override { return dims_; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    const double x0 = params[0][0];
    const double x1 = params[0][1];
    const double r[2] = {10.0 * (x1 - x0 * x0), 1.0 - x0};
    const double J[2][2] = {{-20.0 * x0, 10.0}, {-1.0, 0.0}};
    for (std::size_t k = 0; k < rows.size(); ++k) {
      residuals[k] = r[rows[k]];
      if (jacobian) {
        jacobian[2 * k] = J[rows[k]][0];
        jacobian[2 * k + 1] = J[rows[k]][1];
      }
    }
  }
  std::size_t memory_bytes() const override { return sizeof(*this); }

 private:
  std::array<int, 1> dims_{2};
};

}  // namespace carat::test
