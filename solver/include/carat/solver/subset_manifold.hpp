#pragma once

/// A variable with some coordinates held constant, as Ceres's SubsetManifold: over a Euclidean
/// space (hold k2 of a camera's intrinsics, or one coordinate of a point) or over any manifold
/// (its tangent coordinates: hold the roll and pitch of an SE(3) pose, xi = [omega, v]). The
/// held coordinates never move; the others move as the base manifold moves them. Blocks see the
/// subset's tangent: AutoDiffBlock and NumericDiffBlock reach it through plus_jacobian() (declare
/// the variable as VariableSize<ambient, tangent - held> and pass the manifold), and their dual
/// numbers narrow with it.

#include <memory>
#include <string>
#include <vector>

#include "carat/solver/manifold.hpp"

namespace carat {

/// `base` with the tangent coordinates `constant_coordinates` held.
class SubsetManifold final : public Manifold {
 public:
  /// A Euclidean space of `size` coordinates with `constant_coordinates` held. Throws
  /// carat::Error as the other constructor does.
  SubsetManifold(int size, std::vector<int> constant_coordinates);
  /// `base` (not null) with its tangent coordinates `constant_coordinates` held: distinct, in
  /// [0, base tangent size), and not all of them (hold a whole variable with
  /// Problem::set_constant()). Throws carat::Error naming the coordinate otherwise.
  SubsetManifold(std::shared_ptr<const Manifold> base, std::vector<int> constant_coordinates);

  int ambient_size() const override { return base_->ambient_size(); }
  int tangent_size() const override { return static_cast<int>(free_.size()); }
  void plus(const double* x, const double* delta, double* x_plus_delta) const override;
  void minus(const double* y, const double* x, double* delta) const override;
  void plus_jacobian(const double* x, double* jacobian) const override;
  bool is_valid(const double* x) const override { return base_->is_valid(x); }
  const char* name() const override { return name_.c_str(); }

  /// The manifold the coordinates are held on.
  const Manifold& base() const { return *base_; }
  /// The base's tangent coordinates that move, ascending.
  const std::vector<int>& free_coordinates() const { return free_; }
  /// The held tangent coordinates, ascending.
  const std::vector<int>& constant_coordinates() const { return held_; }

 private:
  std::shared_ptr<const Manifold> base_;
  std::vector<int> free_, held_;
  std::string name_;
};

}  // namespace carat
