#pragma once

/// The manifold of a BAL camera stepped about its centre (see snavely_camera.hpp for the model).

#include <memory>

#include "carat/solver/manifold.hpp"

namespace carat {

/// A BAL camera [w, t, f, k1, k2] (ambient 9: angle-axis w in radians, translation t in scene
/// units, focal length f in pixels, distortion k1, k2) whose tangent steps are
/// [dw, dc, df, dk1, dk2] about its centre c = -R(w)^T t (world frame, scene units):
/// plus(x, d) = [w + dw, -R(w + dw) (c + dc), f + df, k1 + dk1, k2 + dk2]. A rotation step turns
/// the camera about its own centre instead of about the world origin, so that rotation and
/// position are not coupled by the distance to the origin: Gauss-Newton converges in fewer
/// iterations on scenes far from it (a street of cameras). The cost function is the same.
class BalCameraManifold final : public Manifold {
 public:
  int ambient_size() const override { return 9; }
  int tangent_size() const override { return 9; }
  void plus(const double* x, const double* delta, double* x_plus_delta) const override;
  void minus(const double* y, const double* x, double* delta) const override;
  void plus_jacobian(const double* x, double* jacobian) const override;
  bool is_valid(const double* x) const override;
  const char* name() const override { return "bal_camera"; }
};

/// Shared BalCameraManifold instance.
std::shared_ptr<const Manifold> bal_camera_manifold();

}  // namespace carat
