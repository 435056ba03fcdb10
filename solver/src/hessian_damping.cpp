#include "hessian_damping.hpp"

namespace carat::internal {

Eigen::VectorXd clamped_hessian_diagonal(const Eigen::VectorXd& hessian_diagonal,
                                         const SolverOptions& options) {
  return hessian_diagonal.cwiseMax(options.min_lm_diagonal).cwiseMin(options.max_lm_diagonal);
}

const std::vector<double>& gauss_newton_damping_factors() {
  static const std::vector<double> factors = [] {
    std::vector<double> out;
    for (double lambda = 0.0; lambda <= 1.0; lambda = (lambda == 0.0 ? 1e-12 : lambda * 100.0)) {
      out.push_back(lambda);
    }
    return out;
  }();
  return factors;
}

}  // namespace carat::internal
