#pragma once

// Internal: the lower and upper bounds of a problem's Euclidean coordinates during a solve
// (Problem::set_lower_bound()). Trial points are projected onto the bounds; coordinates at a
// bound whose gradient points out of the box are held for the step (their damping made huge,
// the projected-gradient active set); the gradient test uses the projected gradient.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "carat/solver/problem.hpp"

namespace carat::internal {

class BoundConstraints {
 public:
  /// The bounded coordinates of the free variables of `problem` (var_offset: tangent offset per
  /// variable, -1 for constant ones).
  BoundConstraints(const Problem& problem, const std::vector<int>& var_offset);

  /// Whether no coordinate is bounded.
  bool empty() const { return entries_.empty(); }
  /// "" when every bounded value of x (ambient storage) is within its bounds; else a message
  /// naming the first variable and coordinate that is not.
  std::string outside(const double* x) const;
  /// Clamps the bounded values of x onto their bounds; true if one moved.
  bool project(double* x) const;
  /// Adds a damping that holds every active coordinate (at a bound, the gradient pointing out of
  /// the box) to `damping`.
  void hold_active(const double* x, const Eigen::VectorXd& gradient,
                   Eigen::VectorXd* damping) const;
  /// Zeroes the gradient of every active coordinate (the projected gradient's support).
  void project_gradient(const double* x, Eigen::VectorXd* gradient) const;

 private:
  struct Entry {
    std::size_t ambient;  ///< index into the stored values
    int tangent;          ///< index into the tangent vector of the system
    double lower, upper;  ///< the bounds
    int variable, coordinate;
  };
  /// Whether entry e is at a bound with the gradient pointing out of the box.
  static bool active(const Entry& e, double value, double gradient);

  std::vector<Entry> entries_;
};

}  // namespace carat::internal
