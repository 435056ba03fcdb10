// The relative-pose autodiff block: a GICP functor written in T_ij equals the analytic GICP
// block and compresses to 29 rows exact for both poses.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>
#include <vector>

#include "carat/coreset/compress.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/relative_pose_autodiff_block.hpp"
#include "carat/solver/block_checker.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/se3.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using test::random_pose;

/// carat's GICP row written as a functor of T_ij: W (mu_target - T_ij mu_source).
struct GicpDatum {
  Eigen::Vector3d target, source;
  Eigen::Matrix3d W;  // upper triangular, W^T W = (C_target + R C_source R^T)^-1
};
struct GicpFunctor {
  template <typename T>
  bool operator()(const GicpDatum& d, const lie::Pose<T>& T_ij, T* residuals) const {
    const Eigen::Matrix<T, 3, 1> e = d.target.cast<T>() - T_ij.act(d.source.cast<T>());
    const Eigen::Matrix<T, 3, 1> r = d.W.cast<T>() * e;
    for (int k = 0; k < 3; ++k) residuals[k] = r[k];
    return true;
  }
};

TEST(RelativePoseAutoDiffBlockTest, EqualsTheAnalyticGicpBlockAndCompressesTo29Rows) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n;
  const Eigen::Isometry3d T_world_i = random_pose(rng), T_world_j = random_pose(rng);
  const Eigen::Isometry3d T_ij = T_world_i.inverse() * T_world_j;
  std::vector<GicpCorrespondence> correspondences;
  std::vector<GicpDatum> data;
  for (int k = 0; k < 2000; ++k) {
    Eigen::Matrix3d A, B;
    for (int i = 0; i < 9; ++i) {
      A.data()[i] = n(rng);
      B.data()[i] = n(rng);
    }
    const GicpCorrespondence c{Eigen::Vector3d(n(rng), n(rng), n(rng)) * 5,
                               A * A.transpose() + 0.01 * Eigen::Matrix3d::Identity(),
                               Eigen::Vector3d(n(rng), n(rng), n(rng)) * 5,
                               B * B.transpose() + 0.01 * Eigen::Matrix3d::Identity()};
    correspondences.push_back(c);
    const Eigen::Matrix3d fused = 0.5 * (c.covariance_target + c.covariance_target.transpose()) +
                                  T_ij.linear() * 0.5 *
                                      (c.covariance_source + c.covariance_source.transpose()) *
                                      T_ij.linear().transpose();
    const Eigen::Matrix3d W = Eigen::LLT<Eigen::Matrix3d>(fused.inverse()).matrixU();
    data.push_back({c.mean_target, c.mean_source, W});
  }
  const GicpBlock analytic(correspondences, T_ij);
  const auto autodiff = make_relative_pose_block<3>(GicpFunctor{}, data, "autodiff GICP");
  double xi[7], xj[7];
  se3::to_storage(T_world_i, xi);
  se3::to_storage(T_world_j, xj);
  const double* params[2] = {xi, xj};
  Eigen::VectorXd ra, rb;
  Eigen::MatrixXd Ja, Jb;
  evaluate_full_jacobian(analytic, params, &ra, &Ja);
  evaluate_full_jacobian(*autodiff, params, &rb, &Jb);
  EXPECT_LT((ra - rb).cwiseAbs().maxCoeff(), 1e-12 * ra.cwiseAbs().maxCoeff());
  EXPECT_LT((Ja - Jb).cwiseAbs().maxCoeff(), 1e-12 * Ja.cwiseAbs().maxCoeff());
  const auto se3m = se3_manifold();
  const Manifold* manifolds[2] = {se3m.get(), se3m.get()};
  const BlockCheckReport report = check_residual_block(*autodiff, manifolds, params);
  EXPECT_TRUE(report.ok) << report.summary();
  // Reduced to the 6 tangent columns of T_ij: 29 rows give the full 12 x 12 H, b and c.
  EXPECT_EQ(autodiff->reduced_dim(), 6);
  const auto compressed = compress(autodiff, params);
  EXPECT_EQ(compressed->num_rows(), 29);
  Eigen::VectorXd r_full, r_small;
  Eigen::MatrixXd J_full, J_small;
  evaluate_full_jacobian(*autodiff, params, &r_full, &J_full);
  evaluate_full_jacobian(*compressed, params, &r_small, &J_small);
  const Eigen::MatrixXd H_full = J_full.transpose() * J_full;
  const Eigen::MatrixXd H_small = J_small.transpose() * J_small;
  EXPECT_LT((H_full - H_small).norm(), 1e-12 * H_full.norm());
  EXPECT_LT((J_full.transpose() * r_full - J_small.transpose() * r_small).norm(),
            1e-12 * (J_full.transpose() * r_full).norm());
  EXPECT_NEAR(r_small.squaredNorm(), r_full.squaredNorm(), 1e-12 * r_full.squaredNorm());
  EXPECT_LE(compressed->memory_bytes(),
            29 * (sizeof(GicpDatum) + sizeof(std::uint32_t)) + 29 * (sizeof(int) + sizeof(double)));
}

}  // namespace
}  // namespace carat
