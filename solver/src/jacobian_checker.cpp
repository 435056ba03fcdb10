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
  // One paragraph, as Ceres's gradient checker reports a block: the verdict, how many entries
  // are off and in which columns (variable and tangent coordinate), and the worst entry.
  const double allowed = options.absolute_tolerance + options.relative_tolerance * scale;
  std::vector<int> column_variable, column_tangent;
  for (std::size_t v = 0; v < dims.size(); ++v) {
    for (int k = 0; k < dims[v]; ++k) {
      column_variable.push_back(static_cast<int>(v));
      column_tangent.push_back(k);
    }
  }
  const auto column_name = [&](Eigen::Index c) {
    return "column " + std::to_string(c) + " (variable " +
           std::to_string(column_variable[static_cast<std::size_t>(c)]) + ", tangent " +
           std::to_string(column_tangent[static_cast<std::size_t>(c)]) + ")";
  };
  char buffer[512];
  std::string text;
  if (!finite) {
    text = "NON-FINITE: the analytic or numeric Jacobian or the residuals are not finite";
  } else {
    long bad = 0;
    std::vector<Eigen::Index> bad_columns;
    for (Eigen::Index c = 0; c < diff.cols(); ++c) {
      const long in_column = (diff.col(c).array() > allowed).count();
      bad += in_column;
      if (in_column > 0) bad_columns.push_back(c);
    }
    std::snprintf(buffer, sizeof(buffer),
                  "%s: %ld of %ld Jacobian entries differ by more than %.3e",
                  result.ok ? "ok" : "MISMATCH", bad, static_cast<long>(diff.size()), allowed);
    text = buffer;
    if (!bad_columns.empty()) {
      text += ", in ";
      for (std::size_t k = 0; k < bad_columns.size() && k < 6; ++k) {
        text += (k ? ", " : "") + column_name(bad_columns[k]);
      }
      if (bad_columns.size() > 6)
        text += " and " + std::to_string(bad_columns.size() - 6) + " more";
    }
  }
  if (diff.size()) {
    std::snprintf(buffer, sizeof(buffer),
                  "; largest at row %d, %s: analytic %.6e, numeric %.6e (|difference| %.3e, "
                  "relative to the largest numeric entry %.3e)",
                  result.worst_row, column_name(wc).c_str(), result.analytic(wr, wc),
                  result.numeric(wr, wc), result.max_abs_error, result.max_rel_error);
    text += buffer;
  }
  result.message = text;
  return result;
}

}  // namespace carat
