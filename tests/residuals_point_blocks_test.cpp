// Point-to-point and point-to-plane blocks: numeric Jacobians for both poses, row extraction,
// exact compression, bad input.
#include <gtest/gtest.h>

#include <numeric>
#include <random>

#include "carat/base/error.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/residuals/point_to_plane_block.hpp"
#include "carat/residuals/point_to_point_block.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/se3.hpp"

namespace carat {
namespace {

struct Data {
  std::vector<Eigen::Vector3d> target, normal, source;
  double pose_i[7];
  double pose_j[7];
};

Data make_data(int n, std::uint64_t seed, double motion) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Data d;
  for (int k = 0; k < n; ++k) {
    d.source.emplace_back(10 * normal(rng), 10 * normal(rng), normal(rng));
    d.target.push_back(d.source.back() +
                       0.2 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
    d.normal.emplace_back(normal(rng), normal(rng), normal(rng));
  }
  se3::Vector6d a, b;
  for (int i = 0; i < 6; ++i) {
    a[i] = motion * normal(rng);
    b[i] = motion * normal(rng);
  }
  se3::to_storage(se3::exp(a), d.pose_i);
  se3::to_storage(se3::exp(b), d.pose_j);
  return d;
}

const Manifold* const kManifolds[2] = {se3_manifold().get(), se3_manifold().get()};

TEST(PointBlocksTest, NumericJacobiansAtIdentityAndRandomStates) {
  for (double motion : {0.0, 0.4}) {
    Data d = make_data(15, 4, motion);
    const double* params[2] = {d.pose_i, d.pose_j};
    const PointToPointBlock p2p(d.target, d.source);
    const PointToPlaneBlock p2l(d.target, d.normal, d.source);
    EXPECT_EQ(p2p.num_rows(), 45);
    EXPECT_EQ(p2l.num_rows(), 15);
    const JacobianCheckResult a = check_jacobians(p2p, kManifolds, params);
    const JacobianCheckResult b = check_jacobians(p2l, kManifolds, params);
    EXPECT_TRUE(a.ok) << a.message;
    EXPECT_TRUE(b.ok) << b.message;
  }
}

TEST(PointBlocksTest, ExtractedRowsAndExactCompression) {
  Data d = make_data(4000, 5, 0.3);
  const double* params[2] = {d.pose_i, d.pose_j};
  auto p2p = std::make_shared<PointToPointBlock>(d.target, d.source);
  auto p2l = std::make_shared<PointToPlaneBlock>(d.target, d.normal, d.source);
  for (const std::shared_ptr<const ResidualBlock>& block :
       {std::shared_ptr<const ResidualBlock>(p2p), std::shared_ptr<const ResidualBlock>(p2l)}) {
    const std::vector<int> rows = {7, 1, 2, 999};
    const auto extracted = block->extract_rows(rows);
    Eigen::VectorXd r1(4), r2(4);
    Eigen::Matrix<double, 4, 6, Eigen::RowMajor> J1, J2;
    block->evaluate_rows(params, rows, r1.data(), J1.data());
    std::vector<int> local(4);
    std::iota(local.begin(), local.end(), 0);
    extracted->evaluate_rows(params, local, r2.data(), J2.data());
    EXPECT_EQ(r1, r2);
    EXPECT_EQ(J1, J2);
    const auto compressed = compress(block, params);
    EXPECT_EQ(compressed->num_rows(), 29);
    // Point-to-plane rows take their weights into their normals; point-to-point rows keep one
    // beside each row.
    EXPECT_EQ(compressed->folded(), block == p2l);
    EXPECT_EQ(compressed->memory_bytes(), block == p2l ? 29 * 9 * sizeof(double)
                                                       : compressed->inner().memory_bytes() +
                                                             29 * (sizeof(int) + sizeof(double)));
    Eigen::VectorXd r, rc;
    Eigen::MatrixXd J, Jc;
    evaluate_full_jacobian(*block, params, &r, &J);
    evaluate_full_jacobian(*compressed, params, &rc, &Jc);
    const Eigen::MatrixXd H = J.transpose() * J;
    EXPECT_LE((H - Jc.transpose() * Jc).norm() / H.norm(), 1e-12);
    const Eigen::VectorXd b = J.transpose() * r;
    EXPECT_LE((b - Jc.transpose() * rc).norm() / b.norm(), 1e-12);
  }
}

TEST(PointBlocksTest, BadInput) {
  const std::vector<Eigen::Vector3d> one = {Eigen::Vector3d::Zero()};
  const std::vector<Eigen::Vector3d> two = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()};
  try {
    PointToPointBlock block(one, two);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "PointToPointBlock: 1 target points but 2 source points");
  }
  try {
    PointToPlaneBlock block(one, one, one);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "PointToPlaneBlock: normal 0 has zero length");
  }
  EXPECT_THROW(PointToPointBlock({}, {}), Error);
}

}  // namespace
}  // namespace carat
