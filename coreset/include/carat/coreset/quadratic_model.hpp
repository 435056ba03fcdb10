#pragma once

/// The quadratic model (H, b, c) of least-squares rows and relative errors between two models.

#include <Eigen/Core>
#include <algorithm>
#include <span>

namespace carat {

/// H = J^T W J, b = J^T W e, c = e^T W e (W diagonal: row weights, all 1 when none are given).
struct QuadraticModel {
  Eigen::MatrixXd H;  ///< r x r
  Eigen::VectorXd b;  ///< r
  double c = 0.0;     ///< scalar
};

/// Relative differences of two quadratic models (absolute where the reference is zero).
struct QuadraticModelError {
  double H = 0.0;  ///< |H - H~|_F / |H|_F
  double b = 0.0;  ///< |b - b~| / |b|
  double c = 0.0;  ///< |c - c~| / c
  /// Largest of the three.
  double max() const { return std::max(H, std::max(b, c)); }
};

/// The model of all rows (J_r row-major N x r, e), in long double accumulation for reference use.
QuadraticModel quadratic_model(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>&
        J_r,
    const Eigen::Ref<const Eigen::VectorXd>& e);

/// The model of a weighted subset of rows.
QuadraticModel quadratic_model(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>&
        J_r,
    const Eigen::Ref<const Eigen::VectorXd>& e, std::span<const int> rows,
    std::span<const double> weights);

/// Relative errors of `approximation` against `reference`.
QuadraticModelError relative_error(const QuadraticModel& reference,
                                   const QuadraticModel& approximation);

}  // namespace carat
