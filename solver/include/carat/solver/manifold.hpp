#pragma once

/// Manifolds: how a variable's stored values move along a tangent step.

#include <memory>

namespace carat {

/// The space a variable lives in: ambient storage of ambient_size() doubles, updated by
/// tangent steps of tangent_size() doubles through plus(); minus() is its local inverse.
class Manifold {
 public:
  virtual ~Manifold() = default;
  /// Number of doubles stored for one value.
  virtual int ambient_size() const = 0;
  /// Number of degrees of freedom (the dimension of a tangent step).
  virtual int tangent_size() const = 0;
  /// x_plus_delta = x [+] delta. The output may alias x.
  virtual void plus(const double* x, const double* delta, double* x_plus_delta) const = 0;
  /// delta = y [-] x, so that x [+] (y [-] x) = y (locally).
  virtual void minus(const double* y, const double* x, double* delta) const = 0;
  /// d(x [+] delta) / d delta at delta = 0: ambient_size() x tangent_size(), row-major. The
  /// default takes central differences through plus() (steps of 1e-6); carat's manifolds
  /// override it exactly. Automatic differentiation uses it to reach tangent Jacobians.
  virtual void plus_jacobian(const double* x, double* jacobian) const;
  /// Checks a stored value (finite, normalized where required); false with no side effects.
  virtual bool is_valid(const double* x) const = 0;
  /// Short name for reports ("euclidean(3)", "so3", "se3", "se2").
  virtual const char* name() const = 0;
};

/// R^n with plus(x, d) = x + d.
class EuclideanManifold final : public Manifold {
 public:
  /// An n-dimensional Euclidean space (n >= 1).
  explicit EuclideanManifold(int size);
  int ambient_size() const override { return size_; }
  int tangent_size() const override { return size_; }
  void plus(const double* x, const double* delta, double* x_plus_delta) const override;
  void minus(const double* y, const double* x, double* delta) const override;
  void plus_jacobian(const double* x, double* jacobian) const override;
  bool is_valid(const double* x) const override;
  const char* name() const override { return "euclidean"; }

 private:
  int size_;
};

/// SO(3) stored as a unit quaternion [qx, qy, qz, qw]; plus(q, w) = q * Exp(w) (right).
class SO3Manifold final : public Manifold {
 public:
  int ambient_size() const override { return 4; }
  int tangent_size() const override { return 3; }
  void plus(const double* x, const double* delta, double* x_plus_delta) const override;
  void minus(const double* y, const double* x, double* delta) const override;
  void plus_jacobian(const double* x, double* jacobian) const override;
  bool is_valid(const double* x) const override;
  const char* name() const override { return "so3"; }
};

/// SE(3) stored as [qx, qy, qz, qw, tx, ty, tz]; plus(T, xi) = T * Exp(xi), xi = [omega, v].
class SE3Manifold final : public Manifold {
 public:
  int ambient_size() const override { return 7; }
  int tangent_size() const override { return 6; }
  void plus(const double* x, const double* delta, double* x_plus_delta) const override;
  void minus(const double* y, const double* x, double* delta) const override;
  void plus_jacobian(const double* x, double* jacobian) const override;
  bool is_valid(const double* x) const override;
  const char* name() const override { return "se3"; }
};

/// SE(2) stored as [x, y, theta] (metres, radians; theta in (-pi, pi]); plus(T, xi) =
/// T * Exp(xi), xi = [omega, vx, vy] (see se2.hpp).
class SE2Manifold final : public Manifold {
 public:
  int ambient_size() const override { return 3; }
  int tangent_size() const override { return 3; }
  void plus(const double* x, const double* delta, double* x_plus_delta) const override;
  void minus(const double* y, const double* x, double* delta) const override;
  void plus_jacobian(const double* x, double* jacobian) const override;
  bool is_valid(const double* x) const override;
  const char* name() const override { return "se2"; }
};

/// Shared SE(3) manifold instance (manifolds are stateless).
std::shared_ptr<const Manifold> se3_manifold();
/// Shared SE(2) manifold instance.
std::shared_ptr<const Manifold> se2_manifold();
/// Shared SO(3) manifold instance.
std::shared_ptr<const Manifold> so3_manifold();
/// A Euclidean manifold of the given size.
std::shared_ptr<const Manifold> euclidean_manifold(int size);

}  // namespace carat
