#pragma once

/// Reprojection error of one BAL observation (see snavely_camera.hpp for the camera model): two
/// rows r = f d p - observed (pixels) over a camera (9 parameters: Euclidean, or
/// bal_camera_manifold() stepped about its centre) and a point (Euclidean, 3, scene units). The
/// Jacobian is analytic. The block's cost is 1/2 |r|^2.

#include <Eigen/Core>
#include <array>
#include <span>

#include "carat/residuals/snavely_camera.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// Two rows (x, y) of the BAL reprojection error of one observation; variables: camera, point.
class SnavelyReprojectionBlock final : public ResidualBlock {
 public:
  /// Jacobian of both rows: columns 0-8 the camera's tangent ([w, t, f, k1, k2] with
  /// kParameters, [dw, dc, df, dk1, dk2] with kAboutCentre), 9-11 the point.
  using Jacobian = Eigen::Matrix<double, 2, 12, Eigen::RowMajor>;

  /// The observation (observed_x, observed_y) in pixels, relative to the image centre as in the
  /// BAL files, for a camera variable stepping in `camera_tangent` (kParameters: a Euclidean(9)
  /// variable; kAboutCentre: one on bal_camera_manifold()). A tangent that does not match the
  /// variable's manifold gives wrong Jacobians silently (SolverOptions::check_blocks finds
  /// them). Throws carat::Error if either coordinate is not finite.
  SnavelyReprojectionBlock(double observed_x, double observed_y,
                           BalCameraTangent camera_tangent = BalCameraTangent::kParameters);

  int num_rows() const override { return 2; }
  std::span<const int> tangent_dims() const override { return kDims; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override;
  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override;
  double squared_norm(ParameterPointers params) const override;
  std::size_t memory_bytes() const override { return sizeof(*this); }

  /// Residual (pixels) at `camera` (9 values) and `point` (3); with `jacobian` not null also its
  /// 2 x 12 Jacobian. Non-finite when the point lies in the camera's plane (P_z = 0).
  Eigen::Vector2d evaluate(const double* camera, const double* point, Jacobian* jacobian) const;

  /// The observation, pixels.
  const Eigen::Vector2d& observed() const { return observed_; }
  /// The tangent of the camera variable the Jacobian is taken in.
  BalCameraTangent camera_tangent() const { return camera_tangent_; }

 private:
  static constexpr std::array<int, 2> kDims{9, 3};
  Eigen::Vector2d observed_;
  BalCameraTangent camera_tangent_ = BalCameraTangent::kParameters;
};

}  // namespace carat
