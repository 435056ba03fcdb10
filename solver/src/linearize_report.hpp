#pragma once

// Internal: what one linearization of the whole problem (LinearSystem::linearize()) reports
// beside the system it fills: the cost, the error that stopped it, and where its time went.

#include <string>

namespace carat::internal {

/// Wall seconds of one linearization, split by stage.
struct LinearizeTimes {
  double linearize_s = 0.0;  ///< evaluating the residual blocks (residuals, Jacobians, H, b)
  double assembly_s = 0.0;   ///< gathering the blocks' H and b into the system and the gradient
};

/// The outcome of one linearization.
struct LinearizeReport {
  bool ok = false;      ///< false: a block was not finite (error names it)
  double cost = 0.0;    ///< 1/2 sum rho over every block (when ok)
  std::string error;    ///< the block and row that were not finite (when not ok)
  LinearizeTimes time;  ///< where the time went (also when not ok)
};

}  // namespace carat::internal
