#include "free_directions.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <random>
#include <string>

#include "carat/base/error.hpp"

namespace carat::internal {
namespace {

constexpr int kMaxDirections = 256;
constexpr int kIterations = 4;

/// X <- D^-1/2 Q with D^1/2 X = Q R: columns orthonormal in the metric diag(scale).
void orthonormalize(const Eigen::VectorXd& sqrt_scale, Eigen::MatrixXd* X) {
  const Eigen::MatrixXd scaled = sqrt_scale.asDiagonal() * *X;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(scaled);
  *X = sqrt_scale.cwiseInverse().asDiagonal() *
       (qr.householderQ() * Eigen::MatrixXd::Identity(X->rows(), X->cols()));
}

}  // namespace

Eigen::MatrixXd free_directions(LinearSystem& system, const Eigen::VectorXd& scale,
                                double max_variance_inflation) {
  const int n = system.size();
  double delta = 1e-11;
  bool factorized = false;
  for (; delta <= 1.01e-5 && !factorized; delta *= 100.0) {
    factorized = system.factorize(delta * scale);
  }
  if (!factorized) {
    throw Error(
        "covariance: H is not positive semi-definite (not even H + 1e-5 diag(H) has a Cholesky "
        "factor)");
  }
  const Eigen::VectorXd sqrt_scale = scale.cwiseSqrt();
  std::mt19937 rng(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  int m = std::min(n, 8);
  Eigen::MatrixXd X;
  Eigen::VectorXd x, rhs, hx;
  for (;;) {
    X.resize(n, m);
    for (Eigen::Index k = 0; k < X.size(); ++k) X.data()[k] = normal(rng);
    orthonormalize(sqrt_scale, &X);
    for (int it = 0; it < kIterations; ++it) {
      for (int k = 0; k < m; ++k) {
        rhs = scale.cwiseProduct(X.col(k));
        system.solve(rhs, &x);
        X.col(k) = x;
      }
      orthonormalize(sqrt_scale, &X);
    }
    // Rayleigh-Ritz: X^T D X = I, so the Ritz values are the eigenvalues of X^T H X.
    Eigen::MatrixXd HX(n, m);
    for (int k = 0; k < m; ++k) {
      x = X.col(k);
      system.multiply(x, &hx);
      HX.col(k) = hx;
    }
    Eigen::MatrixXd projected = X.transpose() * HX;
    projected = 0.5 * (projected + projected.transpose()).eval();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(projected);
    const Eigen::VectorXd& theta = eigen.eigenvalues();  // ascending
    int k = 0;
    while (k < m && theta[k] < 1.0 / max_variance_inflation) ++k;
    if (k < m || m == n) {
      if (k == 0) return Eigen::MatrixXd(n, 0);
      const Eigen::MatrixXd N = X * eigen.eigenvectors().leftCols(k);
      const Eigen::HouseholderQR<Eigen::MatrixXd> qr(N);
      return qr.householderQ() * Eigen::MatrixXd::Identity(n, k);
    }
    if (m >= kMaxDirections) {
      throw Error("covariance: H has more than " + std::to_string(kMaxDirections) +
                  " free directions (hold variables constant or add priors)");
    }
    m = std::min(n, 2 * m);
  }
}

}  // namespace carat::internal
