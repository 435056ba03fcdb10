#pragma once

// Internal: the robust loss of each global-registration factor under the options' kernels
// (none, a Cauchy kernel on the factor's squared error, or one on its excess over the factor's
// own minimum), shared by every place that puts factors into a problem.

#include <memory>

#include "carat/registration/global_registration.hpp"
#include "carat/solver/loss_function.hpp"

namespace carat::internal {

/// The kernels of one set of options; of() gives each factor its loss.
class FactorLosses {
 public:
  /// The kernels `options` ask for.
  explicit FactorLosses(const GlobalRegistrationOptions& options) {
    if (options.factor_cauchy_scale > 0.0)
      cauchy_ = std::make_shared<CauchyLoss>(options.factor_cauchy_scale);
    if (options.factor_excess_cauchy_scale > 0.0)
      excess_inner_ = std::make_shared<CauchyLoss>(options.factor_excess_cauchy_scale);
  }

  /// The loss of `factor` (null: plain least squares).
  std::shared_ptr<const LossFunction> of(const RegistrationFactor& factor) const {
    if (excess_inner_) return std::make_shared<ExcessLoss>(factor.minimum, excess_inner_);
    return cauchy_;
  }

 private:
  std::shared_ptr<const LossFunction> cauchy_;
  std::shared_ptr<const LossFunction> excess_inner_;
};

}  // namespace carat::internal
