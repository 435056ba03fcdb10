#pragma once

// Internal: the free directions of a singular H (its numerical null space), found through the
// linear system the solver uses. H + delta diag(H) is factorized with a tiny delta; a block of
// seeded random vectors goes through a few steps of inverse subspace iteration (each step
// multiplies the directions of H's small eigenvalues, relative to diag(H), by about 1 / delta
// against the others), then Rayleigh-Ritz on H in the diag(H) metric: the Ritz values below
// 1 / max_variance_inflation are the free directions. The block grows while all of its Ritz
// values are below that.

#include <Eigen/Core>

#include "linear_system.hpp"

namespace carat::internal {

/// An orthonormal basis (system size x k, k >= 0) of H's free directions; `scale` is H's
/// diagonal with its zeros replaced by 1. Leaves `system` factorized with some damping. Throws
/// carat::Error if not even H + 1e-5 diag(H) can be factorized (H is not positive
/// semi-definite) or if there are more than 256 free directions.
Eigen::MatrixXd free_directions(LinearSystem& system, const Eigen::VectorXd& scale,
                                double max_variance_inflation);

}  // namespace carat::internal
