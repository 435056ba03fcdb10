// Lossless registration blocks: the Gram matrix of rows affine in the relative pose, factored
// into at most 13 rows, against the original GICP / point-to-plane / point-to-point blocks (full
// and extracts) at the reference pose and far from it; numeric Jacobians; rank; bad input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/residuals/point_to_plane_block.hpp"
#include "carat/residuals/point_to_point_block.hpp"
#include "carat/residuals/pose_gram.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/se3.hpp"

namespace carat {
namespace {

using ::testing::HasSubstr;
using ::testing::ThrowsMessage;

/// A LiDAR-like factor: points on a few planes 5-40 m away, plane-shaped covariances (eigenvalues
/// 1e-3, 1, 1 times 0.01 m^2, as carat's covariance estimation regularizes them), target points
/// displaced by up to a few centimetres.
struct Scene {
  std::vector<GicpCorrespondence> gicp;
  std::vector<Eigen::Vector3d> target, normal, source;
};

Scene make_scene(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  const std::vector<std::pair<Eigen::Vector3d, double>> planes = {
      {Eigen::Vector3d::UnitZ(), -1.8},
      {Eigen::Vector3d::UnitX(), 12.0},
      {Eigen::Vector3d(0.6, -0.8, 0.0), -25.0},
      {Eigen::Vector3d(-0.1, 1.0, 0.05).normalized(), 31.0}};
  Scene s;
  for (int k = 0; k < n; ++k) {
    const auto& [normal, offset] = planes[static_cast<std::size_t>(k) % planes.size()];
    Eigen::Vector3d p(40.0 * u(rng), 40.0 * u(rng), 3.0 * u(rng));
    p += (offset - normal.dot(p)) * normal;  // onto the plane
    const Eigen::Matrix3d basis =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), normal).toRotationMatrix();
    const Eigen::Matrix3d C =
        basis * Eigen::Vector3d(0.01, 0.01, 1e-5).asDiagonal() * basis.transpose();
    const Eigen::Vector3d q = p + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    s.gicp.push_back({q, C, p, C});
    s.target.push_back(q);
    s.normal.push_back(normal);
    s.source.push_back(p);
  }
  return s;
}

struct Poses {
  double i[7];
  double j[7];
};

/// Poses i, j with T_i^-1 T_j = T_ref Exp(delta) (T_i itself random).
Poses poses_for(const Eigen::Isometry3d& T_ref, const se3::Vector6d& delta, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  se3::Vector6d a;
  for (int k = 0; k < 6; ++k) a[k] = 0.5 * normal(rng);
  const Eigen::Isometry3d T_i = se3::exp(a);
  Poses p;
  se3::to_storage(T_i, p.i);
  se3::to_storage(T_i * T_ref * se3::exp(delta), p.j);
  return p;
}

struct Model {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, 6);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(6);
  double c = 0.0;
};

Model model_of(const ResidualBlock& block, const Poses& poses) {
  const double* params[2] = {poses.i, poses.j};
  Model m;
  m.c = block.accumulate(params, m.H, m.b);
  return m;
}

/// The largest of the relative differences of H, b and c.
double relative_difference(const Model& a, const Model& b) {
  return std::max({(a.H - b.H).norm() / a.H.norm(), (a.b - b.b).norm() / a.b.norm(),
                   std::abs(a.c - b.c) / a.c});
}

/// Relative moves from the reference: none, 1 cm / 0.1 deg, 0.5 m / 5 deg, 5 m / 90 deg.
std::vector<se3::Vector6d> moves() {
  std::vector<se3::Vector6d> out;
  for (const auto& [metres, degrees] :
       {std::pair{0.0, 0.0}, std::pair{0.01, 0.1}, std::pair{0.5, 5.0}, std::pair{5.0, 90.0}}) {
    se3::Vector6d d;
    d << Eigen::Vector3d(1.0, -2.0, 0.5).normalized() * degrees * M_PI / 180.0,
        Eigen::Vector3d(-0.3, 1.0, 0.2).normalized() * metres;
    out.push_back(d);
  }
  return out;
}

const Manifold* const kManifolds[2] = {se3_manifold().get(), se3_manifold().get()};

TEST(LosslessBlockTest, EqualsEveryRegistrationBlockAtEveryPose) {
  const Scene s = make_scene(6000, 3);
  se3::Vector6d xi;
  xi << 0.02, -0.01, 0.3, 1.5, -0.4, 0.05;
  const Eigen::Isometry3d T_ref = se3::exp(xi);
  auto gicp = std::make_shared<GicpBlock>(s.gicp, T_ref);
  auto p2l = std::make_shared<PointToPlaneBlock>(s.target, s.normal, s.source);
  auto p2p = std::make_shared<PointToPointBlock>(s.target, s.source);
  std::vector<int> some_rows;
  for (int k = 0; k < 3000; k += 7) some_rows.push_back(k);
  const std::vector<std::pair<std::string, std::shared_ptr<const ResidualBlock>>> blocks = {
      {"gicp", gicp},
      {"gicp extract", gicp->extract_rows(some_rows)},
      {"point-to-plane", p2l},
      {"point-to-point", p2p},
      {"point-to-point extract", p2p->extract_rows(some_rows)}};
  for (const auto& [name, block] : blocks) {
    const auto* affine = dynamic_cast<const AffinePoseRows*>(block.get());
    ASSERT_NE(affine, nullptr) << name;
    const PoseGram gram = affine->pose_gram(T_ref);
    EXPECT_EQ(gram.rows, static_cast<std::size_t>(block->num_rows())) << name;
    const LosslessRegistrationBlock lossless(gram);
    EXPECT_EQ(lossless.num_rows(), 13) << name;  // points on four planes: full rank
    EXPECT_EQ(lossless.original_rows(), gram.rows) << name;
    EXPECT_LE(lossless.memory_bytes(), 900u) << name;
    std::uint64_t seed = 1;
    for (const se3::Vector6d& delta : moves()) {
      const Poses poses = poses_for(T_ref, delta, seed++);
      const double difference =
          relative_difference(model_of(*block, poses), model_of(lossless, poses));
      // Measured at most 2.2e-15 here, the 90 degree move included: rounding only.
      EXPECT_LT(difference, 1e-13) << name << " moved by " << delta.transpose();
    }
    // The block's exact form is these rows, about the relative pose of the values it is given.
    const Poses at_reference = poses_for(T_ref, se3::Vector6d::Zero(), 9);
    const double* params[2] = {at_reference.i, at_reference.j};
    const std::shared_ptr<const ResidualBlock> form = block->exact_form(params);
    ASSERT_NE(form, nullptr) << name;
    EXPECT_EQ(form->num_rows(), 13) << name;
    const Poses far = poses_for(T_ref, moves().back(), 10);
    EXPECT_LT(relative_difference(model_of(*block, far), model_of(*form, far)), 1e-13) << name;
  }
}

TEST(LosslessBlockTest, NumericJacobiansAndSquaredNorm) {
  const Scene s = make_scene(200, 4);
  const GicpBlock gicp(s.gicp, Eigen::Isometry3d::Identity());
  se3::Vector6d xi;
  xi << 0.1, 0.2, -0.3, 0.5, 1.0, -0.2;
  const LosslessRegistrationBlock lossless(gicp.pose_gram(se3::exp(xi)));
  for (const se3::Vector6d& delta : moves()) {
    const Poses poses = poses_for(se3::exp(xi), delta, 9);
    const double* params[2] = {poses.i, poses.j};
    const JacobianCheckResult check = check_jacobians(lossless, kManifolds, params);
    EXPECT_TRUE(check.ok) << check.message;
    const double c = gicp.squared_norm(params);
    EXPECT_NEAR(lossless.squared_norm(params), c, 1e-11 * c);
  }
}

TEST(LosslessBlockTest, RowsNumberTheRankOfTheGram) {
  // Every point on the plane z = 0 with normal z: the coefficients span R(2, 0) and R(2, 1) (the
  // points have no z), t_z and the constant, so four rows hold the whole cost.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  std::vector<Eigen::Vector3d> target, normal, source;
  for (int k = 0; k < 500; ++k) {
    source.emplace_back(u(rng), u(rng), 0.0);
    target.push_back(source.back() + Eigen::Vector3d(0.01 * u(rng), 0.01 * u(rng), 0.002 * u(rng)));
    normal.push_back(Eigen::Vector3d::UnitZ());
  }
  const PointToPlaneBlock plane(target, normal, source);
  const LosslessRegistrationBlock lossless(plane.pose_gram(Eigen::Isometry3d::Identity()));
  EXPECT_EQ(lossless.num_rows(), 4);
  for (const se3::Vector6d& delta : moves()) {
    const Poses poses = poses_for(Eigen::Isometry3d::Identity(), delta, 11);
    EXPECT_LT(relative_difference(model_of(plane, poses), model_of(lossless, poses)), 1e-13);
  }
  // One point-to-point correspondence: three rows.
  const std::vector<Eigen::Vector3d> a{Eigen::Vector3d(1.0, 2.0, 3.0)};
  const std::vector<Eigen::Vector3d> b{Eigen::Vector3d(1.1, 2.0, 2.9)};
  const PointToPointBlock one(a, b);
  EXPECT_EQ(LosslessRegistrationBlock(one.pose_gram(Eigen::Isometry3d::Identity())).num_rows(), 3);
}

TEST(LosslessBlockTest, RowsCanBeAskedForInAnyOrderWithRepeats) {
  const Scene s = make_scene(300, 8);
  const GicpBlock gicp(s.gicp, Eigen::Isometry3d::Identity());
  std::vector<Eigen::Vector3d> target, normal, source;
  for (int k = 0; k < 50; ++k) {  // points on one plane: four rows
    target.push_back(s.target[4 * static_cast<std::size_t>(k)]);
    normal.push_back(s.normal[4 * static_cast<std::size_t>(k)]);
    source.push_back(s.source[4 * static_cast<std::size_t>(k)]);
  }
  const PointToPlaneBlock plane(target, normal, source);
  const Poses poses = poses_for(Eigen::Isometry3d::Identity(), moves()[2], 21);
  const double* params[2] = {poses.i, poses.j};
  for (const auto& [block, rows] :
       {std::pair{LosslessRegistrationBlock(gicp.pose_gram(Eigen::Isometry3d::Identity())),
                  std::vector<int>{12, 0, 5, 5, 3}},
        std::pair{LosslessRegistrationBlock(plane.pose_gram(Eigen::Isometry3d::Identity())),
                  std::vector<int>{3, 0, 3}}}) {
    const int n = block.num_rows();
    std::vector<int> all(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) all[static_cast<std::size_t>(k)] = k;
    std::vector<double> r_all(all.size()), J_all(6 * all.size());
    block.evaluate_rows(params, all, r_all.data(), J_all.data());
    std::vector<double> r(rows.size()), J(6 * rows.size());
    block.evaluate_rows(params, rows, r.data(), J.data());
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto row = static_cast<std::size_t>(rows[k]);
      EXPECT_EQ(r[k], r_all[row]) << "row " << row;
      for (int c = 0; c < 6; ++c) EXPECT_EQ(J[6 * k + c], J_all[6 * row + c]) << "row " << row;
    }
  }
}

TEST(LosslessBlockTest, ATiltedPlaneNeedsFourRowsAndTheMinimumIsHeldFromAFarReference) {
  // Point-to-plane rows on a tilted plane away from the origin: still four coefficients (the
  // normal's part of R's rows times the in-plane coordinates, t along the normal, constant).
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.2, 0.93).normalized();
  const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
  se3::Vector6d xi;
  xi << 0.05, -0.1, 0.2, 3.0, -1.0, 0.5;
  const Eigen::Isometry3d T_true = se3::exp(xi);  // maps source points onto the target plane
  std::vector<Eigen::Vector3d> target, normal, source;
  for (int k = 0; k < 800; ++k) {
    const Eigen::Vector3d q = Eigen::Vector3d(5.0, 7.0, -2.0) + u(rng) * e1 + u(rng) * e2;
    target.push_back(q + noise(rng) * n);
    normal.push_back(n);
    source.push_back(T_true.inverse() * (q + 0.02 * u(rng) * e1));  // slid along the plane
  }
  const PointToPlaneBlock plane(target, normal, source);
  se3::Vector6d far;
  far << 0.2, 0.1, -0.15, 1.0, -0.5, 0.8;  // about 15 degrees and 1.4 m from T_true
  const Eigen::Isometry3d T_ref = T_true * se3::exp(far);
  const LosslessRegistrationBlock lossless(plane.pose_gram(T_ref));
  EXPECT_EQ(lossless.num_rows(), 4);
  // At T_true the cost is the noise alone (8e-6 of the cost at T_ref): y is large and the Gram
  // matrix's terms nearly cancel. The Gram squares that cancellation (its entries carry rounding
  // of the size of the terms), so the cost itself is held to ~1e-10 relative there (measured
  // 6e-11), while H and b stay at rounding relative to their scale.
  const Poses at_minimum = poses_for(T_true, se3::Vector6d::Zero(), 23);
  const Model a = model_of(plane, at_minimum);
  const Model b = model_of(lossless, at_minimum);
  const Model reference = model_of(plane, poses_for(T_ref, se3::Vector6d::Zero(), 23));
  EXPECT_LT(a.c, 1e-3 * reference.c);
  EXPECT_NEAR(b.c, a.c, 1e-9 * a.c);
  EXPECT_LT((a.H - b.H).norm(), 1e-13 * a.H.norm());          // measured 4e-16
  EXPECT_LT((a.b - b.b).norm(), 1e-13 * reference.b.norm());  // measured 3e-16
}

TEST(LosslessBlockTest, RejectsBadGramMatrices) {
  const Scene s = make_scene(100, 6);
  const PoseGram good =
      GicpBlock(s.gicp, Eigen::Isometry3d::Identity()).pose_gram(Eigen::Isometry3d::Identity());
  PoseGram bad = good;
  bad.gram(3, 4) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("the Gram matrix is not finite")));
  bad = good;
  bad.gram(0, 5) += 1.0;
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("the Gram matrix is not symmetric")));
  bad = good;
  bad.gram(2, 2) = -1.0;
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("not positive semidefinite (diagonal 2")));
  bad = good;
  bad.gram(12, 0) = bad.gram(0, 12) = 2.0 * std::sqrt(bad.gram(0, 0) * bad.gram(12, 12));
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("not positive semidefinite (a pivot of")));
  bad = good;
  bad.gram.row(5).setZero();
  bad.gram.col(5).setZero();
  bad.gram(5, 7) = bad.gram(7, 5) = 1.0;
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("(diagonal 5 is 0 but row 5 is not)")));
  bad = good;
  bad.gram.setZero();
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("the Gram matrix is zero")));
  bad = good;
  bad.embedding.source_centre.x() = std::numeric_limits<double>::infinity();
  EXPECT_THAT([&] { LosslessRegistrationBlock block(bad); },
              ThrowsMessage<Error>(HasSubstr("reference pose or the source centre is not finite")));
}

}  // namespace
}  // namespace carat
