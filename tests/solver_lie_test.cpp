// Property tests for SO(3)/SE(3) and the manifolds (manif/Sophus style).
#include <gtest/gtest.h>

#include <random>
#include <sstream>
#include <string>

#include "carat/base/error.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/so3.hpp"

namespace carat {
namespace {

class LieTest : public ::testing::TestWithParam<double> {
 protected:
  // Tangent vectors of magnitude GetParam() (0 = exactly identity), random directions.
  Eigen::Vector3d random_rotation_vector() {
    Eigen::Vector3d w(normal_(rng_), normal_(rng_), normal_(rng_));
    return w.normalized() * GetParam();
  }
  se3::Vector6d random_tangent() {
    se3::Vector6d xi;
    xi.head<3>() = random_rotation_vector();
    xi.tail<3>() =
        Eigen::Vector3d(normal_(rng_), normal_(rng_), normal_(rng_)) * (1.0 + GetParam());
    return xi;
  }
  std::mt19937_64 rng_{42};
  std::normal_distribution<double> normal_;
};

TEST_P(LieTest, So3ExpLogRoundTrip) {
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d w = random_rotation_vector();
    EXPECT_LT((so3::log(so3::exp(w)) - w).norm(), 1e-12) << w.transpose();
  }
}

TEST_P(LieTest, So3ExpMatchesAngleAxis) {
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d w = random_rotation_vector();
    const Eigen::Matrix3d expected =
        w.norm() > 0 ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix()
                     : Eigen::Matrix3d::Identity();
    EXPECT_LT((so3::exp(w).toRotationMatrix() - expected).norm(), 1e-14);
  }
}

TEST_P(LieTest, Se3ExpLogRoundTrip) {
  for (int trial = 0; trial < 50; ++trial) {
    const se3::Vector6d xi = random_tangent();
    EXPECT_LT((se3::log(se3::exp(xi)) - xi).norm(), 1e-11) << xi.transpose();
  }
}

TEST_P(LieTest, RightJacobianMatchesCentralDifferences) {
  // Exp(w + d) ~= Exp(w) Exp(J_r(w) d): compare J_r with numeric Log(Exp(w)^-1 Exp(w + h e_k)) / h.
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::Vector3d w = random_rotation_vector();
    Eigen::Matrix3d numeric;
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(k) * h;
      const Eigen::Vector3d plus = so3::log(so3::exp(w).conjugate() * so3::exp(w + e));
      const Eigen::Vector3d minus = so3::log(so3::exp(w).conjugate() * so3::exp(w - e));
      numeric.col(k) = (plus - minus) / (2 * h);
    }
    EXPECT_LT((so3::right_jacobian(w) - numeric).norm(), 1e-8);
    EXPECT_LT(
        (so3::right_jacobian_inverse(w) * so3::right_jacobian(w) - Eigen::Matrix3d::Identity())
            .norm(),
        1e-12);
  }
}

TEST_P(LieTest, AdjointMovesTangentsAcross) {
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d T = se3::exp(random_tangent());
    const se3::Vector6d xi = random_tangent() * 0.1;
    const Eigen::Isometry3d left = T * se3::exp(xi);
    const Eigen::Isometry3d right = se3::exp(se3::adjoint(T) * xi) * T;
    EXPECT_LT((left.matrix() - right.matrix()).norm(), 1e-11);
  }
}

TEST_P(LieTest, Se3ManifoldPlusMinusInverse) {
  const SE3Manifold m;
  for (int trial = 0; trial < 30; ++trial) {
    double x[7], y[7], delta[6], back[6];
    se3::to_storage(se3::exp(random_tangent()), x);
    const se3::Vector6d xi = random_tangent();
    if (xi.head<3>().norm() >= M_PI - 1e-6) continue;  // Log is the principal branch
    Eigen::Map<se3::Vector6d> delta_map(delta);
    delta_map = xi;
    m.plus(x, delta, y);
    m.minus(y, x, back);
    EXPECT_LT((Eigen::Map<se3::Vector6d>(back) - xi).norm(), 1e-10);
    // Right perturbation: plus(T, xi) = T * Exp(xi).
    const Eigen::Isometry3d expected = se3::from_storage(x) * se3::exp(xi);
    EXPECT_LT((se3::from_storage(y).matrix() - expected.matrix()).norm(), 1e-12);
  }
}

TEST_P(LieTest, So3ManifoldPlusMinusInverse) {
  const SO3Manifold m;
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::Quaterniond q =
        so3::exp(random_rotation_vector() + Eigen::Vector3d(0.3, -0.2, 0.1));
    double x[4] = {q.x(), q.y(), q.z(), q.w()};
    const Eigen::Vector3d w = random_rotation_vector();
    if (w.norm() >= M_PI - 1e-6) continue;
    double y[4], back[3];
    m.plus(x, w.data(), y);
    m.minus(y, x, back);
    EXPECT_LT((Eigen::Map<Eigen::Vector3d>(back) - w).norm(), 1e-10);
  }
}

INSTANTIATE_TEST_SUITE_P(Magnitudes, LieTest, ::testing::Values(0.0, 1e-9, 1e-4, 0.5, 2.0, 3.1),
                         [](const ::testing::TestParamInfo<double>& param_info) {
                           // e.g. "angle_1e_09", "angle_0_5": digits and underscores only
                           std::ostringstream text;
                           text << "angle_" << param_info.param;
                           std::string name = text.str();
                           for (char& c : name) {
                             if (c == '.' || c == '-' || c == '+') c = '_';
                           }
                           return name;
                         });

TEST(ManifoldTest, EuclideanPlusMinus) {
  const EuclideanManifold m(3);
  const double x[3] = {1, 2, 3};
  const double d[3] = {0.5, -1, 2};
  double y[3], back[3];
  m.plus(x, d, y);
  m.minus(y, x, back);
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(y[i], x[i] + d[i]);
    EXPECT_DOUBLE_EQ(back[i], d[i]);
  }
}

TEST(ManifoldTest, ValidityChecks) {
  const SE3Manifold se3m;
  const double good[7] = {0, 0, 0, 1, 1, 2, 3};
  const double not_unit[7] = {0, 0, 0, 2, 1, 2, 3};
  const double nan[7] = {0, 0, 0, 1, std::nan(""), 2, 3};
  EXPECT_TRUE(se3m.is_valid(good));
  EXPECT_FALSE(se3m.is_valid(not_unit));
  EXPECT_FALSE(se3m.is_valid(nan));
  EXPECT_THROW(EuclideanManifold(0), Error);
}

}  // namespace
}  // namespace carat
