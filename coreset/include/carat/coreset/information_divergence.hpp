#pragma once

/// How far an approximate Hessian is from the original one, as the Kullback-Leibler divergence
/// between the Gaussians they are the information matrices of (Koide et al. 2023, Table II).

#include <Eigen/Core>

namespace carat {

/// KL(N(0, H^-1) || N(0, H~^-1)) = 1/2 (log(|H| / |H~|) + tr(H^-1 H~) - d), computed from
/// the eigenvalues of L^-1 (H~ - H) L^-T (H = L L^T) so that it is >= 0 and exactly 0 when
/// H~ == H. Throws carat::Error when the sizes differ, a value is not finite, H is not
/// positive definite, or H~ is not (an eigenvalue of H^-1 H~ below 1e-12 counts as singular).
double information_kld(const Eigen::MatrixXd& H, const Eigen::MatrixXd& H_tilde);

/// Normalized KLD in [0, 1): 1 - exp(-information_kld(H, H~)).
double normalized_information_kld(const Eigen::MatrixXd& H, const Eigen::MatrixXd& H_tilde);

}  // namespace carat
