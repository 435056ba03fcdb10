#include "trust_region_strategy.hpp"

#include <algorithm>

#include "hessian_damping.hpp"

namespace carat::internal {

TrustRegionStrategy::TrustRegionStrategy(const SolverOptions& options)
    : options_(options),
      radius_(options.lm_start == LmStart::kGaussNewton ? options.gauss_newton_phase_radius
                                                        : options.initial_trust_region_radius),
      gauss_newton_phase_(options.lm_start == LmStart::kGaussNewton) {}

void TrustRegionStrategy::end_gauss_newton_phase() {
  gauss_newton_phase_ = false;
  radius_ = options_.initial_trust_region_radius;
  shrink_factor_ = 2.0;
}

void TrustRegionStrategy::damping(const Eigen::VectorXd& hessian_diagonal,
                                  Eigen::VectorXd* damping) const {
  *damping = clamped_hessian_diagonal(hessian_diagonal, options_) / radius_;
}

bool TrustRegionStrategy::accepts(const StepQuality& step) const {
  return step.cost_is_finite && step.gain_ratio > options_.min_relative_decrease;
}

void TrustRegionStrategy::on_accepted(double gain_ratio) {
  if (gauss_newton_phase_) {
    if (!(gain_ratio >= options_.gauss_newton_phase_min_gain)) end_gauss_newton_phase();
    return;
  }
  const double t = 2.0 * gain_ratio - 1.0;
  radius_ = std::min(options_.max_trust_region_radius,
                     radius_ / std::max(1.0 / options_.max_trust_region_growth, 1.0 - t * t * t));
  shrink_factor_ = 2.0;
}

void TrustRegionStrategy::on_rejected() {
  if (gauss_newton_phase_) {
    end_gauss_newton_phase();
    return;
  }
  radius_ /= shrink_factor_;
  shrink_factor_ *= 2.0;
}

}  // namespace carat::internal
