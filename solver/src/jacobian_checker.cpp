#include "carat/solver/jacobian_checker.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

void evaluate_full_jacobian(const ResidualBlock& block, ParameterPointers params,
                            Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian) {
  const int n = block.num_rows();
  const int r = block.reduced_dim();
  const int D = block.tangent_dim();
  std::vector<int> rows(static_cast<std::size_t>(n));
  std::iota(rows.begin(), rows.end(), 0);
  residuals->resize(n);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Jr(n, r);
  block.evaluate_rows(params, rows, residuals->data(), Jr.data());
  if (r == D) {
    *jacobian = Jr;
  } else {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> A(r, D);
    block.reduced_map(params, A.data());
    *jacobian = Jr * A;
  }
}

JacobianCheckResult check_jacobians(const ResidualBlock& block,
                                    std::span<const Manifold* const> manifolds,
                                    ParameterPointers params, const JacobianCheckOptions& options) {
  const auto dims = block.tangent_dims();
  if (manifolds.size() != dims.size() || params.size() != dims.size()) {
    throw Error("check_jacobians: the block has " + std::to_string(dims.size()) +
                " variables but " + std::to_string(manifolds.size()) + " manifolds and " +
                std::to_string(params.size()) + " parameter pointers were given");
  }
  JacobianCheckResult result;
  Eigen::VectorXd residuals;
  evaluate_full_jacobian(block, params, &residuals, &result.analytic);
  const int n = block.num_rows();
  result.numeric.setZero(n, block.tangent_dim());

  std::vector<int> rows(static_cast<std::size_t>(n));
  std::iota(rows.begin(), rows.end(), 0);
  Eigen::VectorXd plus_r(n), minus_r(n);
  int column = 0;
  for (std::size_t v = 0; v < dims.size(); ++v) {
    const Manifold& m = *manifolds[v];
    std::vector<double> x_plus(static_cast<std::size_t>(m.ambient_size()));
    std::vector<double> x_minus(x_plus.size());
    std::vector<double> delta(static_cast<std::size_t>(m.tangent_size()), 0.0);
    std::vector<const double*> perturbed(params.begin(), params.end());
    for (int k = 0; k < m.tangent_size(); ++k) {
      delta.assign(delta.size(), 0.0);
      delta[static_cast<std::size_t>(k)] = options.step;
      m.plus(params[v], delta.data(), x_plus.data());
      delta[static_cast<std::size_t>(k)] = -options.step;
      m.plus(params[v], delta.data(), x_minus.data());
      perturbed[v] = x_plus.data();
      block.evaluate_rows(perturbed, rows, plus_r.data(), nullptr);
      perturbed[v] = x_minus.data();
      block.evaluate_rows(perturbed, rows, minus_r.data(), nullptr);
      perturbed[v] = params[v];
      result.numeric.col(column++) = (plus_r - minus_r) / (2.0 * options.step);
    }
  }
  const Eigen::MatrixXd diff = (result.analytic - result.numeric).cwiseAbs();
  const double scale = std::max(1.0, result.numeric.cwiseAbs().maxCoeff());
  Eigen::Index wr = 0, wc = 0;
  result.max_abs_error = diff.size() ? diff.maxCoeff(&wr, &wc) : 0.0;
  result.worst_row = static_cast<int>(wr);
  result.worst_col = static_cast<int>(wc);
  result.max_rel_error = result.max_abs_error / scale;
  const bool finite =
      result.analytic.allFinite() && result.numeric.allFinite() && residuals.allFinite();
  result.ok = finite && result.max_abs_error <=
                            options.absolute_tolerance + options.relative_tolerance * scale;
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer),
                "%s: max |J - J_numeric| = %.3e at row %d, column %d (analytic %.6e, numeric %.6e)",
                result.ok ? "ok" : (finite ? "MISMATCH" : "NON-FINITE"), result.max_abs_error,
                result.worst_row, result.worst_col, diff.size() ? result.analytic(wr, wc) : 0.0,
                diff.size() ? result.numeric(wr, wc) : 0.0);
  result.message = buffer;
  return result;
}

}  // namespace carat
