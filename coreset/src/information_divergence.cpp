#include "carat/coreset/information_divergence.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>

#include "carat/base/error.hpp"

namespace carat {

double information_kld(const Eigen::MatrixXd& H, const Eigen::MatrixXd& H_tilde) {
  if (H.rows() != H.cols() || H_tilde.rows() != H.rows() || H_tilde.cols() != H.cols() ||
      H.rows() == 0) {
    throw Error("information_kld: H is " + std::to_string(H.rows()) + " x " +
                std::to_string(H.cols()) + " but H~ is " + std::to_string(H_tilde.rows()) + " x " +
                std::to_string(H_tilde.cols()));
  }
  if (!H.allFinite() || !H_tilde.allFinite()) throw Error("information_kld: non-finite entries");
  const Eigen::LLT<Eigen::MatrixXd> llt(H);
  if (llt.info() != Eigen::Success) throw Error("information_kld: H is not positive definite");
  // With H = L L^T, the eigenvalues 1 + mu_i of L^-1 H~ L^-T give
  // KL = 1/2 sum_i (mu_i - log(1 + mu_i)). The mu_i come from the difference H~ - H, so the
  // rounding scales with the difference, not with H, and every term is >= 0.
  Eigen::MatrixXd D = H_tilde - H;
  llt.matrixL().solveInPlace(D);
  const Eigen::MatrixXd M = llt.matrixL().solve(D.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (M + M.transpose()),
                                                           Eigen::EigenvaluesOnly);
  double kld = 0.0;
  for (Eigen::Index i = 0; i < eig.eigenvalues().size(); ++i) {
    const double mu = eig.eigenvalues()[i];
    // 1 + mu is an eigenvalue of H^-1 H~; below 1e-12 H~ is singular to working precision.
    if (!(mu > -1.0 + 1e-12)) throw Error("information_kld: H~ is not positive definite");
    kld += mu - std::log1p(mu);
  }
  return 0.5 * kld;
}

double normalized_information_kld(const Eigen::MatrixXd& H, const Eigen::MatrixXd& H_tilde) {
  return -std::expm1(-information_kld(H, H_tilde));
}

}  // namespace carat
