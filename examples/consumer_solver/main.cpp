// Fits y = exp(m x + c) with an automatically differentiated block, through carat::solver alone.
#include <carat/base/version.hpp>
#include <carat/solver/autodiff_block.hpp>
#include <carat/solver/solve.hpp>
#include <cmath>
#include <cstdio>
#include <vector>

namespace {

/// Residual of one observation (x, y): y - exp(m x + c).
struct ExponentialResidual {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, T* residual) const {
    using std::exp;
    residual[0] = T(xy.y()) - exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};

}  // namespace

int main() {
  std::vector<Eigen::Vector2d> data;
  for (int k = 0; k < 50; ++k) {
    const double x = 0.1 * k;
    data.emplace_back(x, std::exp(0.3 * x + 0.1));  // noise-free: the fit is exact
  }
  carat::Problem problem;
  const carat::VariableId mc = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  problem.add_residual_block(
      carat::make_autodiff_block<1, carat::VariableSize<2>>(ExponentialResidual{}, data), {mc});
  carat::SolverOptions options;
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-15;
  const carat::SolverSummary summary = carat::solve(options, problem);
  const double m = problem.value(mc)[0];
  const double c = problem.value(mc)[1];
  std::printf("%s\n", summary.brief_report().c_str());
  if (std::abs(m - 0.3) > 1e-9 || std::abs(c - 0.1) > 1e-9) {
    std::printf("consumer_solver: FAILED (m %.12f, c %.12f)\n", m, c);
    return 1;
  }
  std::printf("consumer_solver: ok (carat %s)\n", carat::version());
  return 0;
}
