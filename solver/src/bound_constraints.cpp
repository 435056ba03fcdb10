#include "bound_constraints.hpp"

#include <algorithm>
#include <cmath>

#include "carat/base/error.hpp"
#include "carat/solver/subset_manifold.hpp"

namespace carat::internal {

BoundConstraints::BoundConstraints(const Problem& problem, const std::vector<int>& var_offset) {
  const auto lower = problem.all_lower_bounds();
  const auto upper = problem.all_upper_bounds();
  if (lower.empty()) return;
  for (int v = 0; v < problem.num_variables(); ++v) {
    const int tangent_offset = var_offset[static_cast<std::size_t>(v)];
    if (tangent_offset < 0) continue;  // constant: never moves
    const VariableId id{v};
    const Manifold& m = problem.manifold(id);
    const auto* subset = dynamic_cast<const SubsetManifold*>(&m);
    const std::size_t offset = problem.value_offset(id);
    for (int c = 0; c < m.ambient_size(); ++c) {
      const std::size_t k = offset + static_cast<std::size_t>(c);
      if (std::isinf(lower[k]) && std::isinf(upper[k])) continue;
      int tangent = c;
      if (subset) {  // a Euclidean base: ambient coordinate c is tangent coordinate c there
        const auto& free = subset->free_coordinates();
        const auto it = std::find(free.begin(), free.end(), c);
        if (it == free.end()) continue;  // held: never moves
        tangent = static_cast<int>(it - free.begin());
      }
      entries_.push_back({k, tangent_offset + tangent, lower[k], upper[k], v, c});
    }
  }
}

std::string BoundConstraints::outside(const double* x) const {
  for (const Entry& e : entries_) {
    const double value = x[e.ambient];
    if (value < e.lower || value > e.upper) {
      return "variable " + std::to_string(e.variable) + ", coordinate " +
             std::to_string(e.coordinate) + ": the value " + message_number(value) +
             " is outside its bounds [" + message_number(e.lower) + ", " + message_number(e.upper) +
             "]";
    }
  }
  return {};
}

bool BoundConstraints::project(double* x) const {
  bool moved = false;
  for (const Entry& e : entries_) {
    const double clamped = std::clamp(x[e.ambient], e.lower, e.upper);
    if (clamped != x[e.ambient]) {
      x[e.ambient] = clamped;
      moved = true;
    }
  }
  return moved;
}

bool BoundConstraints::active(const Entry& e, double value, double gradient) {
  // The descent direction -gradient leaves the box through the bound the value sits on.
  return (value <= e.lower && gradient > 0.0) || (value >= e.upper && gradient < 0.0);
}

void BoundConstraints::hold_active(const double* x, const Eigen::VectorXd& gradient,
                                   Eigen::VectorXd* damping) const {
  for (const Entry& e : entries_) {
    if (active(e, x[e.ambient], gradient[e.tangent])) {
      // Large against any curvature a problem has: the step in that coordinate is ~0, then the
      // projection puts it exactly on the bound.
      (*damping)[e.tangent] += 1e20 * std::max(1.0, std::abs((*damping)[e.tangent]));
    }
  }
}

void BoundConstraints::project_gradient(const double* x, Eigen::VectorXd* gradient) const {
  for (const Entry& e : entries_) {
    if (active(e, x[e.ambient], (*gradient)[e.tangent])) (*gradient)[e.tangent] = 0.0;
  }
}

}  // namespace carat::internal
