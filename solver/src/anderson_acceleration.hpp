#pragma once

// Internal: Anderson acceleration of the steps of a slow, linearly converging tail. With one
// factorization M kept for several iterations, the iteration x <- x + f(x), f(x) = -M^-1 g(x),
// is a fixed-point iteration whose linear rate is set by the few directions where the exact
// Hessian is far flatter than M (gain ratios near 2). Anderson's method combines the last few
// steps so that their linearized residual f is least in the Euclidean norm: on a linear map it
// is GMRES, and it removes those directions in a few iterations instead of tens.

#include <Eigen/Core>
#include <deque>

namespace carat::internal {

/// The last few (step solved, step taken) pairs of one run of a fixed map, and the step
/// Anderson's method (type II, mixing 1) proposes from them.
class AndersonAcceleration {
 public:
  /// Keeps at most `memory` earlier pairs (0: never proposes).
  explicit AndersonAcceleration(int memory) : memory_(memory) {}

  /// Forgets every pair (the map changed, or the run ended).
  void reset() { history_.clear(); }
  /// Records the iteration's solved step `solved` (f at the iterate) and the step `taken` from it.
  void push(const Eigen::VectorXd& solved, const Eigen::VectorXd& taken);
  /// True if a pair is recorded, so propose() can differ from the solved step.
  bool ready() const { return !history_.empty(); }
  /// The accelerated step from the current iterate, whose solved step is `solved`: solved -
  /// (dX + dF) gamma with gamma minimizing |solved - dF gamma|. False (out untouched) if the
  /// least-squares problem is degenerate or the result is not finite.
  bool propose(const Eigen::VectorXd& solved, Eigen::VectorXd* out) const;

 private:
  struct Pair {
    Eigen::VectorXd solved;
    Eigen::VectorXd taken;
  };
  int memory_;
  std::deque<Pair> history_;
};

}  // namespace carat::internal
