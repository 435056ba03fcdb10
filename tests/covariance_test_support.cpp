#include "covariance_test_support.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <numeric>

namespace carat::test {

Eigen::MatrixXd dense_hessian(const Problem& problem, std::vector<int>* offsets) {
  offsets->assign(static_cast<std::size_t>(problem.num_variables()), -1);
  int n = 0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    if (problem.is_constant(VariableId{v})) continue;
    (*offsets)[static_cast<std::size_t>(v)] = n;
    n += problem.manifold(VariableId{v}).tangent_size();
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  for (const auto& entry : problem.blocks()) {
    const ResidualBlock& block = *entry.block;
    std::vector<const double*> params;
    for (VariableId v : entry.variables) params.push_back(problem.value(v).data());
    const int rows = block.num_rows();
    const int r = block.reduced_dim();
    const int D = block.tangent_dim();
    std::vector<int> all(static_cast<std::size_t>(rows));
    std::iota(all.begin(), all.end(), 0);
    Eigen::VectorXd residual(rows);
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Jr(rows, r), A(r, D);
    block.evaluate_rows(params, all, residual.data(), Jr.data());
    block.reduced_map(params, A.data());
    const Eigen::MatrixXd J = Jr * A;
    Eigen::MatrixXd Hb = J.transpose() * J;
    if (entry.loss) {
      const double s = residual.squaredNorm();
      const LossValue lv = entry.loss->evaluate(s);
      const Eigen::VectorXd g = J.transpose() * residual;
      if (lv.rho2 != 0.0 && lv.rho1 + 2.0 * s * lv.rho2 > 0.0) {
        Hb = lv.rho1 * Hb + 2.0 * lv.rho2 * g * g.transpose();
      } else {
        Hb *= lv.rho1;
      }
    }
    int local_a = 0;
    for (VariableId a : entry.variables) {
      const int da = problem.manifold(a).tangent_size();
      int local_b = 0;
      for (VariableId b : entry.variables) {
        const int db = problem.manifold(b).tangent_size();
        const int oa = (*offsets)[static_cast<std::size_t>(a.index)];
        const int ob = (*offsets)[static_cast<std::size_t>(b.index)];
        if (oa >= 0 && ob >= 0) H.block(oa, ob, da, db) += Hb.block(local_a, local_b, da, db);
        local_b += db;
      }
      local_a += da;
    }
  }
  return H;
}

Eigen::MatrixXd dense_pseudo_inverse(const Eigen::MatrixXd& H, int nullity) {
  using MatrixL = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  const Eigen::SelfAdjointEigenSolver<MatrixL> eigen(H.cast<long double>());
  const Eigen::Index n = H.rows();
  const MatrixL U = eigen.eigenvectors().rightCols(n - nullity);
  const auto inverse = eigen.eigenvalues().tail(n - nullity).cwiseInverse();
  return (U * inverse.asDiagonal() * U.transpose()).cast<double>();
}

Eigen::MatrixXd dense_kept_gauge(const Eigen::MatrixXd& H, int nullity,
                                 const std::vector<char>& kept) {
  using MatrixL = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  const Eigen::Index n = H.rows();
  const Eigen::SelfAdjointEigenSolver<MatrixL> eigen(H.cast<long double>());
  const MatrixL N = eigen.eigenvectors().leftCols(nullity);
  const MatrixL U = eigen.eigenvectors().rightCols(n - nullity);
  const MatrixL pinv =
      U * eigen.eigenvalues().tail(n - nullity).cwiseInverse().asDiagonal() * U.transpose();
  Eigen::Index m = 0;
  for (const char k : kept) m += k ? 1 : 0;
  MatrixL E = MatrixL::Zero(n, m);  // n x m selection of the kept coordinates
  for (Eigen::Index j = 0, c = 0; j < n; ++j) {
    if (kept[static_cast<std::size_t>(j)]) E(j, c++) = 1.0L;
  }
  const MatrixL N_kept = E.transpose() * N;
  const Eigen::HouseholderQR<MatrixL> qr(N_kept);
  const MatrixL M = qr.householderQ() * MatrixL::Identity(N_kept.rows(), nullity);
  const MatrixL T = (N_kept.transpose() * N_kept).ldlt().solve(N_kept.transpose() * M);
  const MatrixL P = MatrixL::Identity(n, n) - N * T * M.transpose() * E.transpose();
  return (P * pinv * P.transpose()).cast<double>();
}

Eigen::MatrixXd dense_inverse(const Eigen::MatrixXd& H) {
  using MatrixL = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  const MatrixL HL = H.cast<long double>();
  return HL.llt().solve(MatrixL::Identity(H.rows(), H.cols())).cast<double>();
}

double relative_error(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  return (A - B).norm() / B.norm();
}

}  // namespace carat::test
