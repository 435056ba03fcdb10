#pragma once

// Internal: the Levenberg-Marquardt trust region. The system is damped by clamped diag(H)
// divided by the radius mu. A step is taken when its trial cost is finite and its gain ratio
// rho exceeds min_relative_decrease; mu then grows by Nielsen's rule,
// mu / max(1 / max_trust_region_growth, 1 - (2 rho - 1)^3), up to max_trust_region_radius.
// A rejected step, or a factorization that is not positive definite, divides mu by 2, then by 4,
// 8, ... while the rejections go on in a row; the next accepted step starts over at 2.
// With lm_start kGaussNewton, mu starts at gauss_newton_phase_radius and stays there while every
// step's gain ratio is at least gauss_newton_phase_min_gain; the first step below it, a
// rejection or a failed factorization ends the phase with mu = initial_trust_region_radius (and
// a shrink factor of 2), so the solve goes on as one that started there.

#include <Eigen/Core>

#include "carat/solver/solver_options.hpp"
#include "step_quality.hpp"

namespace carat::internal {

/// The radius of the Levenberg-Marquardt trust region and the rules that move it.
class TrustRegionStrategy {
 public:
  /// Starts at options.initial_trust_region_radius, or at gauss_newton_phase_radius in the
  /// Gauss-Newton phase (lm_start kGaussNewton); reads the LM settings of `options`, whose
  /// max_trust_region_growth and lm_start must be resolved already (solve() resolves both).
  explicit TrustRegionStrategy(const SolverOptions& options);

  /// The radius mu (dimensionless: the damping is clamped diag(H) / mu).
  double radius() const { return radius_; }
  /// True while the Gauss-Newton phase lasts.
  bool in_gauss_newton_phase() const { return gauss_newton_phase_; }
  /// The divisor the next rejection applies to the radius (2 after an accepted step).
  double shrink_factor() const { return shrink_factor_; }

  /// Writes the damping of the next factorization into *damping: clamped diag(H) / radius.
  void damping(const Eigen::VectorXd& hessian_diagonal, Eigen::VectorXd* damping) const;
  /// True if the step is taken: finite trial cost and gain ratio > min_relative_decrease.
  bool accepts(const StepQuality& step) const;
  /// After an accepted step of gain ratio `gain_ratio`: Nielsen's growth; the shrink factor is 2
  /// (in the Gauss-Newton phase: the radius stays, or the phase ends below its gain).
  void on_accepted(double gain_ratio);
  /// After a rejected step or a failed factorization: radius / shrink factor; the factor doubles
  /// (in the Gauss-Newton phase: the phase ends at initial_trust_region_radius).
  void on_rejected();

 private:
  /// Leaves the Gauss-Newton phase: radius initial_trust_region_radius, shrink factor 2.
  void end_gauss_newton_phase();

  SolverOptions options_;       ///< the LM settings (a copy)
  double radius_;               ///< mu
  double shrink_factor_ = 2.0;  ///< divisor of the next rejection
  bool gauss_newton_phase_;     ///< in the Gauss-Newton phase
};

}  // namespace carat::internal
