#pragma once

// The curve fit y = exp(m x + c) shared by the autodiff and problem-compression tests.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace carat::test {

/// y = exp(m x + c) as one residual row per observation (x, y); mc = (m, c).
struct ExpResidual {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, T* residual) const {
    using std::exp;
    residual[0] = T(xy.y()) - exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};

/// n observations of y = exp(0.3 x + 0.1) on x in [0, 5) with N(0, 0.2^2) noise drawn from `seed`.
inline std::vector<Eigen::Vector2d> curve_data(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::vector<Eigen::Vector2d> data;
  for (int k = 0; k < n; ++k) {
    const double x = 5.0 * k / n;
    data.emplace_back(x, std::exp(0.3 * x + 0.1) + noise(rng));
  }
  return data;
}

}  // namespace carat::test
